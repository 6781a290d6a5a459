"""
Benchmark: how long a blind diagnosis of ten hours of recordings takes.

A campaign of the patrol boat with a concealed current (``simulate_scenario``, 10 runs
of one hour, seed 5) is diagnosed against its nominal physics through the diagnose CLI,
as a user would run it. The baseline, measured in the same run, is the simulation of
the same recordings: the diagnosis integrates the physics over them many times (fits,
bootstrap, held-out forecasts), so its time is reported as a multiple of one pass of
the simulator over the same hours. Goal: ten hours diagnosed in at most five minutes on
a 2-core machine; the first finding must be the concealed current (a diagnosis that
got faster by finding nothing does not count).
"""

import argparse
import contextlib
import json
from pathlib import Path
import sys
import tempfile
import time

GOAL_S_PER_10_HOURS = 300.0
SCENARIO = 'current'

# A run that takes seconds to minutes, for CI (`bench.py --quick diagnose`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--runs', '4', '--hours', '0.25')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this suite's options."""
    parser.add_argument('--runs', type=int, default=10, help='recordings (default 10)')
    parser.add_argument('--hours', type=float, default=1.0,
                        help='hours per recording (default 1)')
    parser.add_argument('--seed', type=int, default=5, help='simulation seed (default 5)')


def run(args) -> dict:
    """Simulate the campaign, diagnose it; return both times, their ratio and the finding."""
    from vessel_diagnosis import cli as diagnose
    from vessel_diagnosis.scenarios import simulate_scenario

    if args.runs < 1 or not args.hours > 0:
        raise SystemExit('bench.py diagnose: error: --runs must be >= 1 and --hours > 0')
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        data = simulate_scenario(SCENARIO, Path(tmp) / 'data', runs=args.runs,
                                 hours=args.hours, seed=args.seed)
        simulated = time.perf_counter() - started
        out = Path(tmp) / 'report'
        started = time.perf_counter()
        # The CLI's summary line is for a person: stderr, so stdout stays one JSON.
        with contextlib.redirect_stdout(sys.stderr):
            code = diagnose.main(['--recordings', str(data), '--physics',
                                  str(data / 'nominal_physics.yaml'), '--out', str(out),
                                  '--quiet'])
        diagnosed = time.perf_counter() - started
        if code != 0:
            raise SystemExit(f'bench.py diagnose: error: the diagnosis ended with exit {code}')
        findings = json.loads((out / 'findings.json').read_text())
    hours = findings['recordings']['hours']
    first = findings['findings'][0]['category'] if findings['findings'] else None
    goal = GOAL_S_PER_10_HOURS * hours / 10.0
    return {
        'suite': 'diagnose',
        'scenario': SCENARIO,
        'recorded_hours': round(hours, 3),
        'simulate_s': round(simulated, 2),
        'diagnose_s': round(diagnosed, 2),
        'diagnose_s_per_recorded_hour': round(diagnosed / hours, 2),
        'diagnose_vs_simulate': round(diagnosed / simulated, 2),
        'first_finding': first,
        'goals': {'diagnose_s': f'<= {goal:g} ({GOAL_S_PER_10_HOURS:g} s per 10 h)',
                  'first_finding': SCENARIO},
        'met': {'diagnose_s': diagnosed <= goal, 'first_finding': first == SCENARIO},
    }
