#!/usr/bin/env python3
r"""
Train the same hybrid on different physics: the ``compare_physics`` program of hybrid_models.

    python offline/compare_physics.py --dataset DIR --out RESULTS \
        --physics nominal=DIR/nominal_physics.yaml augmented=DIAG/augmented_physics.yaml

Reports the relative threshold each physics needs for the same accuracy (``--help`` for
the options); ``ros2 run hybrid_models compare_physics`` is the same program installed.
"""

import sys

from hybrid_models.cli.compare_physics import main

if __name__ == '__main__':
    sys.exit(main())
