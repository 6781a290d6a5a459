r"""
Two models of one study compared seed by seed: an order between them, or a tie.

Usage:  tools/with_env.sh python docs/results/real/analysis/paired_seeds.py STUDY OUT \
            [--first LABEL] [--second LABEL]
STUDY is the --out folder of ``offline/workflow.py`` or ``offline/crossval.py``
(results.json); OUT/paired.md and OUT/paired.json receive the comparison. By default
FIRST is the hybrid on the augmented physics and SECOND the one on the nominal physics.

Both models are trained with the same seeds on the same folds, so seed k of one is
paired with seed k of the other. For the position error at the horizon's end and the
trajectory error over the horizon (pooled over the study's forecasts, as in its table)
the script prints each seed's pair, how many seeds have FIRST ahead, the mean paired
difference with its standard error over seeds, and a paired t-test (scipy) and sign test:
whether the seeds support an order or only a tie.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import numpy as np
from scipy import stats

METRICS = {'at the horizon [m]': 'final_mean', 'trajectory over the horizon [m]': 'mean'}


def per_seed(row: dict, key: str) -> np.ndarray:
    """Return a study row's per-seed pooled trajectory figure ``key`` (m)."""
    return np.array([m['trajectory'][key] for m in row['per_seed_metrics']], np.float64)


def compare(first: np.ndarray, second: np.ndarray) -> dict:
    """Return the paired comparison of two models' per-seed errors (lower is better)."""
    diff = first - second
    n = len(diff)
    t = stats.ttest_rel(first, second) if n > 1 else None
    ahead = int((diff < 0).sum())
    return {'first': first.round(4).tolist(), 'second': second.round(4).tolist(),
            'first_mean': float(first.mean()), 'second_mean': float(second.mean()),
            'first_ahead': ahead, 'seeds': n,
            'mean_difference': float(diff.mean()),
            'standard_error': float(diff.std(ddof=1) / np.sqrt(n)) if n > 1 else None,
            't_test_p': None if t is None else float(t.pvalue),
            'sign_test_p': float(stats.binomtest(ahead, n - int((diff == 0).sum())).pvalue)}


def main(argv: list[str]) -> int:
    """Compare the two rows of the study seed by seed; print and write the result."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('study', type=Path)
    parser.add_argument('out', type=Path)
    parser.add_argument('--first', default='hybrid on augmented physics')
    parser.add_argument('--second', default='hybrid on nominal physics')
    args = parser.parse_args(argv)
    try:
        rows = {r['label']: r for r in
                json.loads((args.study / 'results.json').read_text())['rows']}
        first, second = rows[args.first], rows[args.second]
    except (OSError, json.JSONDecodeError) as exc:
        parser.error(f'{args.study}: no finished study ({exc})')
    except KeyError as exc:
        parser.error(f'{args.study}: no row {exc}; rows: {sorted(rows)}')
    if first['per_seed_metrics'] and len(first['per_seed_metrics']) != len(
            second['per_seed_metrics']):
        parser.error('the two rows have different numbers of seeds')
    result = {name: compare(per_seed(first, key), per_seed(second, key))
              for name, key in METRICS.items()}
    lines = [f'# {args.first} against {args.second}, seed by seed', '',
             f'Study `{args.study.name}`; seed k of one is paired with seed k of the other '
             '(same folds, validation runs and seed).', '',
             '| error | per seed (first / second) | first ahead | mean difference ± se '
             '| paired t-test p | sign test p |', '|---|---|---|---|---|---|']
    for name, c in result.items():
        pairs = ', '.join(f'{a:.2f} / {b:.2f}' for a, b in zip(c['first'], c['second'],
                                                                 strict=True))
        se, p = c['standard_error'], c['t_test_p']   # None with a single seed
        lines.append(f"| {name} | {pairs} | {c['first_ahead']} of {c['seeds']} | "
                     f"{c['mean_difference']:+.3f} ± {'–' if se is None else f'{se:.3f}'} | "
                     f"{'–' if p is None else f'{p:.2f}'} | {c['sign_test_p']:.2f} |")
    text = '\n'.join(lines) + '\n'
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'paired.json').write_text(json.dumps(result, indent=2))
    (args.out / 'paired.md').write_text(text)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
