#!/usr/bin/env python3
"""
Evaluate trained checkpoints on the test runs: the ``evaluate`` program of hybrid_models.

``python offline/evaluate.py --help`` for the options; ``ros2 run hybrid_models
evaluate`` is the same program installed.
"""

import sys

from hybrid_models.cli.evaluate import main

if __name__ == '__main__':
    sys.exit(main())
