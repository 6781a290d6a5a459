"""
Simulate "real" recordings with a concealed effect, and the nominal physics that lacks it.

    python offline/simulate_scenario.py --list
    python offline/simulate_scenario.py --scenario fouling --runs 20 --hours 1 --seed 5 --out DIR
    python offline/simulate_scenario.py --vessel otter --scenario weak_thruster --out DIR
    python offline/simulate_scenario.py --vessel crazyflie_brushless --scenario weak_motor \
        --runs 12 --seconds 40 --out DIR

Scenarios (``vessel_diagnosis/config/scenarios.yaml``), per vessel -- one of each physics
family: the patrol boat (default), the KVLCC2 model (MMG), the Otter (Fossen), the
Crazyflie (multirotor) --: the simulator plus an effect the nominal physics does not
have (a current, hull fouling, missing wind loads, a rudder offset, added resistance, a
weak thruster, a weak rotor, a payload; ``control`` has none). Writes a dataset
(docs/conventions.md, split 60/10/30 by run) and ``DIR/nominal_physics.yaml``: what
``offline/diagnose.py`` and ``offline/compare_physics.py`` are given. The manifest keeps
every run's true sea state, wind and current (a multirotor's: its trajectory kind and
settings). Exit codes: 0 done, 1 bad scenario or output, 2 bad arguments.
"""

import argparse
import json
from pathlib import Path
import sys
import time

from vessel_datasets.format import DatasetError
from vessel_description import VesselError, load_vessel, shipped_vessels
from vessel_diagnosis.scenarios import load_scenario_file, simulate_scenario
from vessel_physics.errors import ConfigError
from vessel_physics.simulation.config import DEFAULT_VESSEL


def shipped_name(vessel: str) -> str:
    """
    Return the shipped vessel a --vessel names: its name, or the path of its file.

    Scenarios belong to the shipped vessels; a file that describes one of them (the same
    description, wherever it lies) is that vessel. A file that only shares a shipped
    vessel's name is refused (VesselError, one line): its scenarios would be another's.
    """
    if vessel in shipped_vessels() or not Path(vessel).suffix:
        return vessel
    given = load_vessel(vessel)
    if given.name in shipped_vessels():
        shipped = load_vessel(given.name)
        if given.to_dict() == shipped.to_dict():
            return given.name
        raise VesselError(f'{vessel} is named {given.name!r} but differs from the shipped '
                          f'vessel of that name, whose scenarios these are')
    return given.name


def main(argv=None) -> int:
    """Parse arguments, simulate, print a JSON summary; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--scenario', help='scenario name (see --list)')
    parser.add_argument('--vessel', default=DEFAULT_VESSEL,
                        help=f'vessel whose scenarios to use (default {DEFAULT_VESSEL})')
    parser.add_argument('--list', action='store_true', help='list the scenarios and exit')
    parser.add_argument('--runs', type=int, default=20, help='number of runs (default 20)')
    parser.add_argument('--hours', type=float, default=None, help='hours per run (default 1)')
    parser.add_argument('--seconds', type=float, default=None,
                        help='seconds per run instead of --hours (a flight of a minute)')
    parser.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    parser.add_argument('--out', type=Path, help='output dataset directory')
    args = parser.parse_args(argv)
    vessels = load_scenario_file()['vessels']
    if args.list:
        for vessel, spec in vessels.items():
            for name, scenario in spec['scenarios'].items():
                print(f'{vessel:12s} {name:16s} '
                      f'{" ".join(str(scenario.get("description", "")).split())}')
        return 0
    try:
        args.vessel = shipped_name(args.vessel)
    except VesselError as exc:
        print(f'simulate_scenario: error: {exc}', file=sys.stderr)
        return 1
    if args.vessel not in vessels:
        print(f'simulate_scenario: error: no scenarios for vessel {args.vessel!r}; vessels '
              f'with scenarios: {", ".join(vessels)}', file=sys.stderr)
        return 1
    scenarios = vessels[args.vessel]['scenarios']
    if not args.scenario or args.out is None:
        parser.error('--scenario and --out are required (or --list)')
    if args.hours is not None and args.seconds is not None:
        parser.error('give --hours or --seconds, not both')
    args.hours = (args.seconds / 3600.0 if args.seconds is not None
                  else 1.0 if args.hours is None else args.hours)
    if args.runs < 1 or not args.hours > 0:
        parser.error(f'--runs must be >= 1 and --hours (--seconds) > 0, got {args.runs} and '
                     f'{args.hours}')
    if args.scenario not in scenarios:
        print(f'simulate_scenario: error: unknown scenario {args.scenario!r} of vessel '
              f'{args.vessel}; known: {", ".join(scenarios)}', file=sys.stderr)
        return 1
    if args.out.exists() and any(args.out.iterdir()):
        print(f'simulate_scenario: error: {args.out} exists and is not empty; choose a new '
              f'directory', file=sys.stderr)
        return 1
    print(f'simulating scenario {args.scenario!r} of {args.vessel}: {args.runs} runs x '
          + (f'{args.seconds:g} s' if args.seconds is not None else f'{args.hours:g} h')
          + f' (seed {args.seed})', file=sys.stderr)
    start = time.monotonic()
    try:
        out = simulate_scenario(args.scenario, args.out, args.runs, args.hours, args.seed,
                                vessel=args.vessel)
    except (ConfigError, DatasetError, OSError) as exc:
        print(f'simulate_scenario: error: {exc}', file=sys.stderr)
        return 1
    print(json.dumps({'scenario': args.scenario, 'vessel': args.vessel, 'out': str(out),
                      'runs': args.runs,
                      'hours': args.hours, 'seed': args.seed,
                      'nominal_physics': str(out / 'nominal_physics.yaml'),
                      'seconds': round(time.monotonic() - start, 1)}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
