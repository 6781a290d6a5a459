"""
Benchmark: the paper-sized batch simulation (96 runs x 1 h, wind and waves on).

The baseline is real time: the ratio is simulated run-seconds per wall-clock second, so
the figure does not depend on what the runs are compared against. Goals: <= 60 s wall,
>= 5,760x real time (96 h in one minute), <= 2 GiB peak memory.
"""

import argparse
from pathlib import Path
import resource
import time

from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.simulator import Simulator

GOAL_WALL_S = 60.0
GOAL_RATIO = 5760.0
GOAL_MEMORY_GIB = 2.0
KIB_PER_GIB = 1024.0 ** 2


# A run that takes seconds to minutes, for CI (`bench.py --quick sim`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--runs', '2', '--hours', '0.02')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this suite's options."""
    parser.add_argument('--runs', type=int, default=96, help='runs (default 96)')
    parser.add_argument('--hours', type=float, default=1.0, help='hours per run (default 1)')
    parser.add_argument('--seed', type=int, default=0, help='seed (default 0)')
    parser.add_argument('--config', type=Path, default=None,
                        help='simulation YAML (default: the package default, waves and '
                             'wind on)')


def run(args) -> dict:
    """Run the batch once and return the figures and goals."""
    cfg = load_simulation(args.config)
    seconds = args.hours * 3600.0
    start = time.perf_counter()
    sim = Simulator(cfg, n_runs=args.runs, seed=args.seed)
    setup = time.perf_counter() - start
    data = sim.run(seconds)
    wall = time.perf_counter() - start
    # ru_maxrss is in KiB on Linux: the whole process's peak, data included.
    peak_gib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / KIB_PER_GIB
    ratio = args.runs * seconds / wall
    steps = int(round(seconds / cfg.dt))
    return {
        'suite': 'sim',
        'runs': args.runs,
        'hours_per_run': args.hours,
        'dt_s': cfg.dt,
        'rk4_steps': steps,
        'samples_per_run': int(data['t'].shape[1]),
        'waves': cfg.waves.enabled, 'wind': cfg.wind.enabled,
        'wall_time_s': round(wall, 2),
        'setup_time_s': round(setup, 2),
        'ms_per_rk4_step_all_runs': round(1e3 * (wall - setup) / steps, 3),
        'real_time_ratio': round(ratio, 1),
        'peak_memory_gib': round(peak_gib, 3),
        'goals': {'wall_time_s': f'<= {GOAL_WALL_S:g}',
                  'real_time_ratio': f'>= {GOAL_RATIO:g}',
                  'peak_memory_gib': f'<= {GOAL_MEMORY_GIB:g}'},
        'met': {'wall_time_s': wall <= GOAL_WALL_S, 'real_time_ratio': ratio >= GOAL_RATIO,
                'peak_memory_gib': peak_gib <= GOAL_MEMORY_GIB},
    }
