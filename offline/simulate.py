#!/usr/bin/env python3
"""
Simulate the patrol vessel and write a dataset: the ``simulate`` program of vessel_datasets.

``python offline/simulate.py --help`` for the options; ``ros2 run vessel_datasets
simulate`` is the same program installed.
"""

import sys

from vessel_datasets.simulate import main

if __name__ == '__main__':
    sys.exit(main())
