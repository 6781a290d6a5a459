#!/usr/bin/env python3
"""
Demo: the simulator and the predictor running together, forecasts checked against truth.

    python offline/demo.py [--minutes 22] [--speed-up 30] [--no-plan] [--out out/demo]

The ``demo`` program of vessel_bringup (what ``make demo`` runs): starts the installed
simulator and predictor, steers the vessel, prints the forecast-against-truth errors and
writes a PNG and JSON (``--help`` for the options); ``ros2 run vessel_bringup demo`` is
the same program installed.
"""

import sys

from vessel_bringup.demo import main

if __name__ == '__main__':
    sys.exit(main())
