#!/usr/bin/env python3
"""
Diagnose, augment the physics, retrain and compare: ``workflow`` of vessel_diagnosis.

``python offline/workflow.py --help`` for the options; ``ros2 run vessel_diagnosis
workflow`` is the same program installed.
"""

import sys

from vessel_diagnosis.cli_workflow import main

if __name__ == '__main__':
    sys.exit(main())
