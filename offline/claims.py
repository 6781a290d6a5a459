#!/usr/bin/env python3
"""
The real-data conversions the docs print, and the figures they promise, kept on every commit.

    python offline/claims.py derive     # convert each, write docs/results/real/claims.json
    python offline/claims.py check      # convert each again, compare with claims.json

Each shared real recording (../shared/real) is converted exactly as its document says
(the command, vessel file and flags the docs print; ``--dry-run``: nothing is written),
and the pooled map checks' figures (slopes, lags, angles, spike counts), the verdict and
the number of runs are recorded. ``check`` fails (exit 1) naming every figure that moved
beyond its tolerance (``TOLERANCE``): a change of code that moves a documented result is
seen at once, and either fixed or the result re-derived with ``derive`` and committed
with the docs that state it. tests/unit/test_real_claims.py runs ``check`` in
``make test`` where ../shared/real is present.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
from pathlib import Path
import re
import sys

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / 'shared' / 'real'
CLAIMS = REPO / 'docs' / 'results' / 'real' / 'claims.json'
# Where each command is printed, and the command (repo-relative paths; REAL stands for
# ../shared/real). The --out of the docs is replaced by --dry-run: nothing is written.
CONVERSIONS = {
    'snuboat': ('docs/results/real/README.md', 'bag_to_dataset', [
        'REAL/snuboat/bags', '--vessel', 'snuboat', '--msg-dir', 'REAL/snuboat/msg',
        '--msg-package', 'snumsg_pkg', '--jobs', '2']),
    'kvlcc2_hsva': ('docs/results/real/kvlcc2_import.md', 'table_to_dataset', [
        'REAL/kvlcc2_hsva/raw_data', '--vessel', 'kvlcc2_hsva', '--holdout',
        'HSVA_CPMC_KVLCC2_Z_20_10_P', 'HSVA_CPMC_KVLCC2_Z_35_05', '--val',
        'HSVA_CPMC_KVLCC2_Z_15_05']),
    'usv': ('docs/results/real/usv_import.md', 'table_to_dataset', [
        'REAL/usv/turnningdata_xy.csv', '--vessel', 'usv', '--split', '1,0,0']),
    'nanodrone': ('docs/results/nanodrone/import.md', 'table_to_dataset', [
        'REAL_NANODRONE_FLIGHTS', '--vessel', 'crazyflie_brushless']),
    'ardupilot_copter_loiter': ('docs/results/real/autopilot_import.md', 'log_to_dataset', [
        'REAL/ardupilot_copter/Loiter_RTL.bin', '--vessel',
        'docs/results/real/autopilot/arducopter_quad.yaml']),
}
# How far a figure may move (absolute), by what it measures; counts must stay equal.
TOLERANCE = {'slope': 0.01, 'seconds': 0.02, 'degrees': 0.25, 'count': 0.0}


def kind_of(check: str) -> str:
    """Return what a check's figure measures (``TOLERANCE``'s keys)."""
    if check.startswith('timing'):
        return 'seconds'
    if check.startswith(('course', 'drift')):
        return 'degrees'
    if check == 'spikes':
        return 'count'
    return 'slope'


def argv_of(name: str) -> list[str]:
    """Return the converter's arguments of one conversion, with the real data's paths."""
    _, _, args = CONVERSIONS[name]
    out = []
    for a in args:
        if a == 'REAL_NANODRONE_FLIGHTS':   # every flight but the one the checks refuse
            out += [str(p) for p in sorted((REAL / 'nanodrone').glob('*/*.parquet'))
                    if not p.stem.endswith('_na')]
        elif a.startswith('REAL/'):
            out.append(str(REAL / a[len('REAL/'):]))
        elif a.endswith('.yaml') and '/' in a:
            out.append(str(REPO / a))
        else:
            out.append(a)
    return out + ['--dry-run', '--quiet', '--out', '/nonexistent-dry-run']


def convert(name: str) -> dict:
    """Run one conversion as its document prints it; return its figures."""
    from vessel_datasets import bag_to_dataset, log_to_dataset, table_to_dataset

    main = {'bag_to_dataset': bag_to_dataset.main, 'table_to_dataset': table_to_dataset.main,
            'log_to_dataset': log_to_dataset.main}[CONVERSIONS[name][1]]
    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        code = main(argv_of(name))
    text = said.getvalue()
    failed = re.search(r'map checks failed \((.*)\);', text)
    failed = failed.group(1) if failed else ''   # names that hold commas themselves
    pooled = {}
    for line in text.splitlines():
        if line.startswith('all runs: check '):
            check, _, result = line[len('all runs: check '):].partition(': ')
            pooled[check] = {'figure': _figure(check, result), 'ok': check not in failed}
    runs = re.findall(r'-> (\d+) run\(s\)', text)
    return {'document': CONVERSIONS[name][0], 'exit': code,
            'runs': sum(int(n) for n in runs), 'checks': pooled}


def _figure(check: str, result: str) -> float | None:
    """Return the number a pooled check line judges (None when skipped)."""
    if result.startswith('skipped') or result == 'none':
        return 0.0 if result == 'none' else None
    if check.startswith('timing'):
        lags = [float(x) for x in re.findall(r'[+-]\d+\.\d+(?= s)', result)]
        return max((abs(x) for x in lags), default=None)
    if check == 'spikes':
        found = re.search(r'-> (\d+) samples', result)
        return float(found.group(1)) if found else 0.0
    found = re.search(r'(?:slope|median(?: difference)?) (-?\d+\.\d+)', result)
    return float(found.group(1)) if found else None


def differences(claimed: dict, now: dict) -> list[str]:
    """Return one line per figure, verdict or count that moved beyond its tolerance."""
    out = []
    for name, c in claimed.items():
        n = now[name]
        if n['exit'] != c['exit']:
            out.append(f"{name}: exit {n['exit']}, the docs' {c['exit']}")
        if n['runs'] != c['runs']:
            out.append(f"{name}: {n['runs']} runs, the docs' {c['runs']}")
        for check, fig in c['checks'].items():
            got = n['checks'].get(check)
            if got is None:
                out.append(f'{name}: check {check!r} no longer reported')
                continue
            if got['ok'] != fig['ok']:
                out.append(f"{name}: {check} ok={got['ok']}, the docs' ok={fig['ok']}")
            a, b = got['figure'], fig['figure']
            tol = TOLERANCE[kind_of(check)]
            if (a is None) != (b is None) or (a is not None and abs(a - b) > tol + 1e-12):
                out.append(f"{name}: {check} {a}, the docs' {b} (tolerance {tol:g})")
    return out


def main(argv=None) -> int:
    """Derive or check the claims; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('action', choices=('derive', 'check'))
    parser.add_argument('--only', nargs='+', choices=sorted(CONVERSIONS),
                        help='these conversions only (default all)')
    args = parser.parse_args(argv)
    if not REAL.is_dir():
        print(f'claims: error: {REAL} (the shared real recordings) is absent', file=sys.stderr)
        return 2
    names = args.only or list(CONVERSIONS)
    now = {}
    for name in names:
        print(f'claims: converting {name} as {CONVERSIONS[name][0]} prints it', file=sys.stderr)
        now[name] = convert(name)
    if args.action == 'derive':
        claims = json.loads(CLAIMS.read_text()) if CLAIMS.is_file() else {}
        claims.update(now)
        CLAIMS.write_text(json.dumps(claims, indent=2) + '\n')
        print(CLAIMS)
        return 0
    claimed = json.loads(CLAIMS.read_text())
    moved = differences({k: claimed[k] for k in names}, now)
    for line in moved:
        print(f'claims: {line}', file=sys.stderr)
    print(json.dumps({'checked': names, 'moved': moved}, indent=2))
    return 1 if moved else 0


if __name__ == '__main__':
    sys.exit(main())
