#!/usr/bin/env python3
"""
Give a hybrid checkpoint calibrated forecast bands from a dataset's validation runs.

    python offline/set_bands.py MODEL.safetensors --dataset DATA

``ros2 run hybrid_models set_bands`` is the same program installed; ``--help`` for the
options.
"""

import sys

from hybrid_models.cli.set_bands import main

if __name__ == '__main__':
    sys.exit(main())
