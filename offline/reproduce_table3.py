#!/usr/bin/env python3
"""
Reproduce Baier et al.'s Table 3 (the quadrotor): the ``reproduce_table3`` program.

    python offline/reproduce_table3.py --dataset DIR --out DIR [--seeds 5] [--peers NPZ]

Trains every model with several seeds, evaluates them on the test runs (the paper's
columns and the nanodrone benchmark's errors per horizon step) and writes table, figures
and REPORT.md with the paper's findings checked (``--help`` for the options);
``ros2 run hybrid_models reproduce_table3`` is the same program installed.
"""

import sys

from hybrid_models.cli.reproduce_table3 import main

if __name__ == '__main__':
    sys.exit(main())
