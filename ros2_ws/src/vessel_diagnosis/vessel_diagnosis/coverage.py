"""
Measured coverage of the diagnosis' 95 % intervals on known-answer scenarios.

A scenario whose simulated physics differs from the nominal one in parameters (a
coefficient weakened on purpose, a value the vessel has and the drawings do not, one
that differs from run to run) has a known answer: the change each parameter needs. Each
seed simulates the scenario afresh, identifies on the diagnosis runs (the held-out runs
left out, as ``diagnose`` does) and checks whether the reported intervals contain

- the simulated value (with ``run_spread``: its mean over runs, the scenario's value), and
- each held-out run's own value: what another run of the same vessel has,

for the reported interval (``ci95``, widened by the between-run spread) and for the
bootstrap's alone (``ci95_noise``). A parameter not found counts as not covered.

Usage: ``python3 -m vessel_diagnosis.coverage --vessel kvlcc2_hsva --scenarios weak_rudder
weak_rudder_varying --seeds 20 --out DIR`` (see --help).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import json
from pathlib import Path
import sys
import tempfile

import numpy as np

from vessel_description import load_vessel
from vessel_diagnosis.library import load_library
from vessel_diagnosis.pipeline import name_missing_physics
from vessel_diagnosis.recordings import load_recordings, split_holdout
from vessel_diagnosis.scenarios import load_scenario, scenario_names, simulate_scenario
from vessel_diagnosis.settings import Settings, load_settings
from vessel_physics.errors import ConfigError

INTERVALS = ('ci95', 'ci95_noise')


def known_changes(scenario) -> dict[str, float]:
    """Return the change each parameter needs: simulated minus nominal value."""
    family = scenario.nominal.family
    nominal = family.parameter_values(scenario.nominal.params)
    simulated = family.parameter_values(scenario.simulation.physics.params)
    return {name: float(simulated[name] - nominal[name]) for name in nominal
            if isinstance(nominal[name], float) and simulated[name] != nominal[name]}


def one_seed(scenario, seed: int, runs: int, seconds: float, settings: Settings,
             work: Path) -> list[dict]:
    """Simulate, identify and check every known parameter once; one row per parameter."""
    data = simulate_scenario(scenario.name, work / f'seed{seed}', runs=runs,
                             hours=seconds / 3600.0, seed=seed, vessel=scenario.vessel)
    recordings = load_recordings([data])
    ev = settings.evaluation
    diag, held, _ = split_holdout(recordings, ev.holdout_fraction, ev.holdout_seed)
    vessel = load_vessel(scenario.vessel)
    family = scenario.nominal.family
    named = name_missing_physics(diag, scenario.nominal, settings,
                                 load_library(None, family), vessel)
    found = {r.get('parameter'): r for r in [*named.records, *named.kept_out]
             if r.get('kind') == 'parameter'}
    index = {r.run_id: i for i, r in enumerate(recordings)}
    rows = []
    for name, change in known_changes(scenario).items():
        nominal = scenario.nominal.parameter(name)
        per_run = [scenario.run_physics(seed, index[r.run_id]).parameter(name) - nominal
                   for r in held]
        record = found.get(name)
        row = {'seed': seed, 'parameter': name, 'truth_change': change,
               'held_out_changes': per_run, 'found': record is not None,
               'estimate': record['coefficient'] if record else None}
        for key in INTERVALS:
            lo, hi = record[key] if record else (np.nan, np.nan)
            row[key] = [lo, hi]
            row[f'{key}_covers_truth'] = bool(lo <= change <= hi)
            row[f'{key}_covers_held_out'] = [bool(lo <= c <= hi) for c in per_run]
        rows.append(row)
    return rows


def summarize(rows: Sequence[dict]) -> dict:
    """Return found rate and coverage shares per parameter (module docstring)."""
    out = {}
    for name in sorted({r['parameter'] for r in rows}):
        mine = [r for r in rows if r['parameter'] == name]
        entry = {'seeds': len(mine), 'found': float(np.mean([r['found'] for r in mine]))}
        for key in INTERVALS:
            entry[f'{key}_truth'] = float(np.mean([r[f'{key}_covers_truth'] for r in mine]))
            held = [c for r in mine for c in r[f'{key}_covers_held_out']]
            entry[f'{key}_held_out'] = float(np.mean(held)) if held else None
            widths = [r[key][1] - r[key][0] for r in mine if r['found']]
            entry[f'{key}_median_width'] = float(np.median(widths)) if widths else None
        out[name] = entry
    return out


def measure(vessel: str, names: Sequence[str], seeds: Sequence[int], runs: int,
            seconds: float, settings: Settings | None = None,
            say: Callable[[str], None] | None = None) -> dict:
    """Return {scenario: {'summary': ..., 'rows': [...]}} over ``seeds``."""
    say = say or (lambda _: None)
    out = {}
    for name in names:
        scenario = load_scenario(name, vessel=vessel)
        if not known_changes(scenario):
            raise ConfigError(f'scenario {vessel}/{name} changes no parameter: it has no '
                              f'known answer to cover')
        cfg = settings or load_settings(family=scenario.nominal.family.name)
        rows = []
        with tempfile.TemporaryDirectory() as work:
            for seed in seeds:
                rows += one_seed(scenario, seed, runs, seconds, cfg, Path(work))
                say(f'{vessel}/{name}: seed {seed} done ({len(rows)} rows)')
        out[name] = {'summary': summarize(rows), 'rows': rows}
    return out


def markdown(vessel: str, result: dict, runs: int, seconds: float) -> str:
    """Return the coverage table of ``measure``'s result."""
    lines = [f'Coverage of the 95 % intervals, {vessel}, {runs} runs of {seconds:g} s per '
             f'seed (widened: ci95; bootstrap alone: ci95_noise).', '',
             '| scenario | parameter | seeds | found | truth: widened | truth: noise only | '
             'held-out runs: widened | held-out runs: noise only | median width: widened | '
             'median width: noise only |', '|' + '---|' * 10]
    for name, entry in result.items():
        for parameter, s in entry['summary'].items():
            cells = [name, parameter, str(s['seeds']), f'{s["found"]:.0%}']
            cells += [_share(s[f'{k}_truth']) for k in INTERVALS]
            cells += [_share(s[f'{k}_held_out']) for k in INTERVALS]
            cells += [_num(s[f'{k}_median_width']) for k in INTERVALS]
            lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines) + '\n'


def _share(value) -> str:
    return '-' if value is None else f'{value:.0%}'


def _num(value) -> str:
    return '-' if value is None else f'{value:.3g}'


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (module docstring)."""
    parser = argparse.ArgumentParser(
        prog='python3 -m vessel_diagnosis.coverage',
        description="Measure how often the diagnosis' 95 %% intervals contain the known "
                    'answer of parameter scenarios (config/scenarios.yaml).')
    parser.add_argument('--vessel', required=True, help='vessel with scenarios')
    parser.add_argument('--scenarios', nargs='+', required=True, help='scenario names')
    parser.add_argument('--seeds', type=int, default=20, help='seeds 0..N-1 (default 20)')
    parser.add_argument('--runs', type=int, default=6, help='runs per seed (default 6)')
    parser.add_argument('--seconds', type=float, default=120.0,
                        help='seconds per run (default 120)')
    parser.add_argument('--out', required=True, help='folder for coverage.json and .md')
    args = parser.parse_args(argv)
    try:
        for name in args.scenarios:
            if name not in scenario_names(args.vessel):
                raise ConfigError(f'unknown scenario {name!r} of vessel {args.vessel!r}')
        result = measure(args.vessel, args.scenarios, range(args.seeds), args.runs,
                         args.seconds, say=lambda m: print(m, file=sys.stderr, flush=True))
    except ConfigError as exc:
        print(f'coverage: {exc}', file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'coverage.json').write_text(json.dumps(result, indent=1) + '\n')
    table = markdown(args.vessel, result, args.runs, args.seconds)
    (out / 'coverage.md').write_text(table)
    print(table)
    return 0


if __name__ == '__main__':
    sys.exit(main())
