#!/usr/bin/env python3
"""
Train one forecasting model from a YAML config: the ``train`` program of hybrid_models.

Runs as one process or under ``torchrun``; ``python offline/train.py --help`` for the
options, ``ros2 run hybrid_models train`` is the same program installed.
"""

import sys

from hybrid_models.cli.train import main

if __name__ == '__main__':
    sys.exit(main())
