#!/usr/bin/env python3
"""
Write the relative threshold a hybrid checkpoint is served with into the checkpoint.

    python offline/set_threshold.py MODEL.safetensors 0.15

``ros2 run hybrid_models set_threshold`` is the same program installed; ``--help`` for
the options.
"""

import sys

from hybrid_models.cli.set_threshold import main

if __name__ == '__main__':
    sys.exit(main())
