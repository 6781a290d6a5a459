#!/usr/bin/env python3
"""
Compare models over seeds and folds of held-out recordings: ``crossval`` of hybrid_models.

``python offline/crossval.py --help`` for the options; ``ros2 run hybrid_models
crossval`` is the same program installed.
"""

import sys

from hybrid_models.cli.crossval import main

if __name__ == '__main__':
    sys.exit(main())
