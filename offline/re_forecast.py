#!/usr/bin/env python3
"""
Re-forecast a recorded bag offline and compare with the forecasts recorded in it.

    python offline/re_forecast.py --bag out/demo_bag [--model PATH] [--vessel NAME]

The ``re_forecast`` program of hybrid_predictor (``--help`` for the options): recomputes
every recorded forecast from the recorded inputs and plan with the same checkpoint and
prints the largest difference live - offline per state as JSON.
"""

import sys

from hybrid_predictor.bag_re_forecast import main

if __name__ == '__main__':
    sys.exit(main())
