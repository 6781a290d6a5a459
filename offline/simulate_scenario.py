#!/usr/bin/env python3
"""
Simulate "real" recordings with a concealed effect, and the nominal physics that lacks it.

    python offline/simulate_scenario.py --scenario fouling --out DIR    # --list: scenarios

The ``simulate_scenario`` program of vessel_diagnosis: writes a dataset and
``DIR/nominal_physics.yaml``, what ``offline/diagnose.py`` and
``offline/compare_physics.py`` are given (``--help`` for the options and exit codes);
``ros2 run vessel_diagnosis simulate_scenario`` is the same program installed.
"""

import sys

from vessel_diagnosis.cli_scenario import main

if __name__ == '__main__':
    sys.exit(main())
