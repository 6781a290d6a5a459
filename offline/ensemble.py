#!/usr/bin/env python3
"""
Serve trained hybrids of one config (seeds) as one ensemble checkpoint.

    python offline/ensemble.py M0.safetensors M1.safetensors --dataset DIR --out E.safetensors

``ros2 run hybrid_models ensemble`` is the same program installed; ``--help`` for the
options.
"""

import sys

from hybrid_models.cli.ensemble import main

if __name__ == '__main__':
    sys.exit(main())
