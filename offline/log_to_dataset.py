#!/usr/bin/env python3
"""
Convert autopilot logs (ArduPilot DataFlash .bin, PX4 ULog .ulg) into a training dataset.

    python offline/log_to_dataset.py LOG... --vessel VESSEL --out DATASET

The ``log_to_dataset`` program of vessel_datasets (``--help`` for the options, the log
map and the exit codes); ``ros2 run vessel_datasets log_to_dataset`` is the same program
installed.
"""

import sys

from vessel_datasets.log_to_dataset import main

if __name__ == '__main__':
    sys.exit(main())
