"""
Simulate a vessel and write a dataset (docs/conventions.md format).

    python offline/simulate.py --out data/ship                    # the paper's 96 x 1 h
    python offline/simulate.py --vessel otter --runs 8 --hours 0.1 --out /tmp/otter
    python offline/simulate.py --vessel crazyflie_brushless --runs 30 --seconds 60 \
        --out data/crazyflie                                       # 30 flights of 60 s
    python offline/simulate.py --config my.yaml --runs 3 --hours 0.1 --seed 7 --out /tmp/ds
    ros2 run vessel_datasets simulate --out data/ship              # the same, installed

The patrol boat is the default; ``--vessel NAME_OR_FILE`` simulates another vessel with
its shipped scenario (vessel_physics/config/simulation/NAME.yaml) or, with ``--config``,
overrides the scenario's vessel.

Runs are simulated together, vectorized (in chunks of --chunk runs), with run k drawn
from the seed sequence (SEED, k): any run can be reproduced alone. Every run is written
as runs/run_NNN.parquet with the measured columns and their noise-free ``*_true``
twins; the runs are split 60/10/30 into train/val/test by a shuffle seeded with SEED.
The manifest records the full configuration (including the vessel parameters), the seed,
package versions and what each run was drawn from: a vessel's sea state and wind, a
multirotor's trajectory (``kind``: square, random, multisine, melon or aggressive, and
its drawn settings). ``--test-kinds melon`` makes the flights of those kinds the test
split (the nano-drone benchmark tests on its melon flights) and splits the others
60:10 into train and val. Progress goes to stderr, the summary (JSON) to stdout. Exit
codes: 0 done, 1 bad configuration or output, 2 bad arguments.
"""

import argparse
import json
import math
from pathlib import Path
import platform
import sys
import time

import numpy as np
import pandas as pd
import scipy
from tqdm import tqdm

from vessel_datasets.format import (
    DEFAULT_FRACTIONS,
    MANIFEST,
    SPLITS,
    DatasetError,
    split_runs,
    write_dataset,
)
from vessel_datasets.synthetic import simulated_run_table, simulation_vessel
from vessel_physics.errors import ConfigError
from vessel_physics.simulation.config import default_config_path, load_simulation
from vessel_physics.simulation.simulator import Simulator
from vessel_physics.simulation.trajectories import KINDS

TOOL = 'offline/simulate.py'
VESSEL_PHYSICS_VERSION = '0.1.0'


def positive_int(text: str) -> int:
    """Parse an integer >= 1 for argparse."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be >= 1, got {value}')
    return value


def non_negative_int(text: str) -> int:
    """Parse an integer >= 0 for argparse."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'must be >= 0, got {value}')
    return value


def positive_float(text: str) -> float:
    """Parse a finite number > 0 for argparse."""
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f'must be a number > 0, got {text}')
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--config', type=Path, default=None,
                        help=f'simulation YAML (default {default_config_path()})')
    parser.add_argument('--vessel', metavar='NAME_OR_FILE',
                        help="vessel file to simulate (default: the scenario's; the patrol "
                             'boat)')
    parser.add_argument('--runs', type=positive_int, default=96,
                        help='number of runs (default 96)')
    duration = parser.add_mutually_exclusive_group()
    duration.add_argument('--hours', type=positive_float, default=None,
                          help='duration of each run in hours (default 1)')
    duration.add_argument('--seconds', type=positive_float, default=None,
                          help='duration of each run in seconds (instead of --hours)')
    parser.add_argument('--seed', type=non_negative_int, default=0,
                        help='seed of the runs and of the train/val/test split (default 0)')
    parser.add_argument('--out', type=Path, required=True, help='dataset directory to write')
    parser.add_argument('--chunk', type=positive_int, default=96,
                        help='runs simulated together (memory vs speed; default 96)')
    parser.add_argument('--test-kinds', nargs='+', choices=KINDS, metavar='KIND',
                        help="a multirotor's flights of these trajectory kinds form the test "
                             f'split, the others train and val ({", ".join(KINDS)})')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing dataset in --out')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    return parser


def run_source(sim: Simulator, j: int, run_index: int, seed: int) -> dict:
    """Return what a run was drawn from (for the manifest): sea and wind, or trajectory."""
    if sim.flies:
        return {'simulator': TOOL, 'seed': seed, 'run_index': run_index,
                **sim.operator.trajectories.describe(j)}
    return {
        'simulator': TOOL, 'seed': seed, 'run_index': run_index,
        'wave_hs_m': float(sim.waves.hs[j]), 'wave_tp_s': float(sim.waves.tp[j]),
        'wave_direction_rad': float(sim.waves.direction[j]),
        'wind_mean_speed_mps': float(sim.wind.mean_speed[j]),
        'wind_from_rad': float(sim.wind.from_ned0[j]),
        'current_speed_mps': float(sim.current.speed0[j]),
        'current_direction_rad': float(sim.current.direction[j]),
    }


def split_by_kind(sources: dict, test_kinds, seed: int) -> dict[str, list[str]]:
    """Return the split: runs of ``test_kinds`` to test, the others 60:10 train and val."""
    test = sorted(r for r, source in sources.items() if source.get('kind') in test_kinds)
    if not test:
        kinds = sorted({source.get('kind') for source in sources.values()} - {None})
        raise DatasetError(f'--test-kinds {" ".join(test_kinds)}: no run flies them (the runs '
                           f'fly {", ".join(kinds) or "no trajectories"})')
    train, val, _ = DEFAULT_FRACTIONS
    rest = split_runs([r for r in sources if r not in test], seed,
                      (train / (train + val), val / (train + val), 0.0))
    return dict(zip(SPLITS, (rest['train'], rest['val'], test), strict=True))


def simulate(args) -> dict:
    """Simulate and write the dataset; return the summary."""
    cfg = load_simulation(args.config, args.vessel)
    out = args.out
    if (out / MANIFEST).exists() and not args.overwrite:
        raise DatasetError(f'{out} already holds a dataset; use --overwrite to replace it')
    if args.test_kinds and cfg.flight is None:
        raise ConfigError(f'--test-kinds: vessel {cfg.vessel.name!r} flies no trajectories '
                          f'(a multirotor does)')
    hours = args.hours if args.seconds is None else args.seconds / 3600.0
    hours = 1.0 if hours is None else hours
    seconds = hours * 3600.0
    n_periods = int(round(seconds * cfg.output_rate_hz))
    vessel = simulation_vessel(cfg)
    if n_periods < 1:
        raise ConfigError(f'a run of {seconds:g} s is shorter than one output period')
    runs, sources = {}, {}
    start = time.perf_counter()
    with tqdm(total=args.runs * n_periods, unit='run-s', unit_scale=1.0 / cfg.output_rate_hz,
              desc='simulating', disable=args.quiet, file=sys.stderr, mininterval=1.0) as bar:
        for first in range(0, args.runs, args.chunk):
            n = min(args.chunk, args.runs - first)
            sim = Simulator(cfg, n_runs=n, seed=args.seed, run_offset=first)
            data = sim.run(n_periods / cfg.output_rate_hz,
                           progress=lambda k, n=n: bar.update(k * n))
            for j in range(n):
                run_id = f'run_{first + j:03d}'
                runs[run_id] = simulated_run_table(data, j, vessel)
                sources[run_id] = run_source(sim, j, first + j, args.seed)
    wall = time.perf_counter() - start
    split = split_by_kind(sources, args.test_kinds, args.seed) if args.test_kinds else None
    provenance = {
        'tool': TOOL,
        'command': [TOOL] + list(sys.argv[1:]),
        'config_file': str(args.config) if args.config else cfg.source,
        'config': cfg.to_dict(),
        'seed': args.seed,
        'runs': args.runs,
        'hours': hours,
        'seconds': seconds,
        'versions': {'python': platform.python_version(), 'numpy': np.__version__,
                     'scipy': scipy.__version__, 'pandas': pd.__version__,
                     'vessel_physics': VESSEL_PHYSICS_VERSION},
        'units': 'SI; angles in rad; shaft and rotor speeds in rad/s; frames NED/FRD '
                 '(docs/conventions.md)',
        'wall_time_s': round(wall, 3),
    }
    write_dataset(out, runs, vessel=vessel, provenance=provenance,
                  seed=args.seed, run_sources=sources, split=split)
    summary = {'out': str(out), 'runs': args.runs, 'samples_per_run': n_periods + 1,
               'seed': args.seed, 'wall_time_s': round(wall, 2),
               'real_time_ratio': round(args.runs * seconds / max(wall, 1e-9), 1)}
    if cfg.flight is not None:
        kinds = [source['kind'] for source in sources.values()]
        summary['kinds'] = {k: kinds.count(k) for k in KINDS if k in kinds}
    return summary


def main(argv=None) -> int:
    """Parse arguments, simulate, write; return the exit code."""
    args = build_parser().parse_args(argv)
    try:
        summary = simulate(args)
    except (ConfigError, DatasetError) as exc:
        print(f'simulate.py: error: {exc}', file=sys.stderr)
        return 1
    except OSError as exc:
        print(f'simulate.py: error: {exc.filename or args.out}: {exc.strerror}', file=sys.stderr)
        return 1
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
