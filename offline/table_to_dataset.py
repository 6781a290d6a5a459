#!/usr/bin/env python3
"""
Convert tabular logs (CSV, whitespace-separated .dat, ...) into a training dataset.

    python offline/table_to_dataset.py FILE_OR_DIR... --vessel VESSEL --out DATASET

The ``table_to_dataset`` program of vessel_datasets (``--help`` for the options, the
column map's checks and the exit codes); ``ros2 run vessel_datasets table_to_dataset`` is
the same program installed.
"""

import sys

from vessel_datasets.table_to_dataset import main

if __name__ == '__main__':
    sys.exit(main())
