#!/usr/bin/env python3
"""
Reproduce Baier et al.'s Table 2: the ``reproduce_table2`` program of hybrid_models.

    python offline/reproduce_table2.py --dataset DIR --out docs/results [--smoke]

Trains every model, evaluates them on the test runs and writes table, figures and
REPORT.md with the paper's claims checked (``--help`` for the options);
``ros2 run hybrid_models reproduce_table2`` is the same program installed.
"""

import sys

from hybrid_models.cli.reproduce_table2 import main

if __name__ == '__main__':
    sys.exit(main())
