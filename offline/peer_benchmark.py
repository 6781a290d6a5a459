#!/usr/bin/env python3
"""
The peer benchmark (NARX, SINDy, deepsysid) on a crossval study (hybrid_models.cli.peers).

``python offline/peer_benchmark.py --help`` for the options; ``ros2 run hybrid_models
peer_benchmark`` is the same program installed. docs/results/peers/README.md has the results.
"""

import sys

from hybrid_models.cli.peers import main

if __name__ == '__main__':
    sys.exit(main())
