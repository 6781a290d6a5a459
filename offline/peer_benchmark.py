#!/usr/bin/env python3
"""
The peer benchmark (NARX, SINDy, deepsysid) on a crossval study: ``peers`` of hybrid_models.

``python offline/peer_benchmark.py --help`` for the options; ``ros2 run hybrid_models
peers`` is the same program installed. docs/results/peers/README.md has the results.
"""

import sys

from hybrid_models.cli.peers import main

if __name__ == '__main__':
    sys.exit(main())
