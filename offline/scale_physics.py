#!/usr/bin/env python3
"""
Write an MMG parameter file for the same hull at another length, by Froude's law.

    python offline/scale_physics.py FILE --length M --out SCALED.yaml

The ``scale_physics`` program of vessel_physics (``--help`` for the options and what
scales how); ``ros2 run vessel_physics scale_physics`` is the same program installed.
"""

import sys

from vessel_physics.mmg.scale import main

if __name__ == '__main__':
    sys.exit(main())
