"""
Simulate a vessel and write a dataset (docs/conventions.md format).

    python offline/simulate.py --out data/ship                    # the paper's 96 x 1 h
    python offline/simulate.py --vessel otter --runs 8 --hours 0.1 --out /tmp/otter
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
package versions and each run's sea state and wind. Progress goes to stderr, the summary
(JSON) to stdout. Exit codes: 0 done, 1 bad configuration or output, 2 bad arguments.
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

from vessel_datasets.format import MANIFEST, DatasetError, write_dataset
from vessel_datasets.synthetic import simulated_run_table, simulation_vessel
from vessel_physics.errors import ConfigError
from vessel_physics.simulation.config import default_config_path, load_simulation
from vessel_physics.simulation.simulator import Simulator

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
    parser.add_argument('--hours', type=positive_float, default=1.0,
                        help='duration of each run in hours (default 1)')
    parser.add_argument('--seed', type=non_negative_int, default=0,
                        help='seed of the runs and of the train/val/test split (default 0)')
    parser.add_argument('--out', type=Path, required=True, help='dataset directory to write')
    parser.add_argument('--chunk', type=positive_int, default=96,
                        help='runs simulated together (memory vs speed; default 96)')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing dataset in --out')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    return parser


def run_source(sim: Simulator, j: int, run_index: int, seed: int) -> dict:
    """Return what a run was drawn from (for the manifest)."""
    return {
        'simulator': TOOL, 'seed': seed, 'run_index': run_index,
        'wave_hs_m': float(sim.waves.hs[j]), 'wave_tp_s': float(sim.waves.tp[j]),
        'wave_direction_rad': float(sim.waves.direction[j]),
        'wind_mean_speed_mps': float(sim.wind.mean_speed[j]),
        'wind_from_rad': float(sim.wind.from_ned0[j]),
        'current_speed_mps': float(sim.current.speed0[j]),
        'current_direction_rad': float(sim.current.direction[j]),
    }


def simulate(args) -> dict:
    """Simulate and write the dataset; return the summary."""
    cfg = load_simulation(args.config, args.vessel)
    out = args.out
    if (out / MANIFEST).exists() and not args.overwrite:
        raise DatasetError(f'{out} already holds a dataset; use --overwrite to replace it')
    seconds = args.hours * 3600.0
    n_periods = int(round(seconds * cfg.output_rate_hz))
    vessel = simulation_vessel(cfg)
    if n_periods < 1:
        raise ConfigError(f'--hours {args.hours} is shorter than one output period')
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
    provenance = {
        'tool': TOOL,
        'command': [TOOL] + list(sys.argv[1:]),
        'config_file': str(args.config) if args.config else cfg.source,
        'config': cfg.to_dict(),
        'seed': args.seed,
        'runs': args.runs,
        'hours': args.hours,
        'versions': {'python': platform.python_version(), 'numpy': np.__version__,
                     'scipy': scipy.__version__, 'pandas': pd.__version__,
                     'vessel_physics': VESSEL_PHYSICS_VERSION},
        'units': 'SI; angles in rad; shaft speed n in rad/s; frames NED/FRD '
                 '(docs/conventions.md)',
        'wall_time_s': round(wall, 3),
    }
    write_dataset(out, runs, vessel=vessel, provenance=provenance,
                  seed=args.seed, run_sources=sources)
    return {'out': str(out), 'runs': args.runs, 'samples_per_run': n_periods + 1,
            'seed': args.seed, 'wall_time_s': round(wall, 2),
            'real_time_ratio': round(args.runs * seconds / max(wall, 1e-9), 1)}


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
