#!/usr/bin/env python3
"""
Diagnose where and why a nominal physics model departs from recordings.

    python offline/diagnose.py --recordings DATA --physics NOMINAL.yaml --out REPORT_DIR

The ``diagnose`` program of vessel_diagnosis: writes report.md, findings.json and, when
it forecasts held-out recordings better, an augmented physics (``--help`` for the options
and exit codes, docs/diagnosis.md for the method); ``ros2 run vessel_diagnosis diagnose``
is the same program installed.
"""

import sys

from vessel_diagnosis.cli import main

if __name__ == '__main__':
    sys.exit(main())
