#!/usr/bin/env python3
"""
Turn a hybrid checkpoint's novelty fade (a bound that fades off its training data) on or off.

    python offline/set_novelty.py MODEL.safetensors on

``ros2 run hybrid_models set_novelty`` is the same program installed; ``--help`` for
the options.
"""

import sys

from hybrid_models.cli.set_novelty import main

if __name__ == '__main__':
    sys.exit(main())
