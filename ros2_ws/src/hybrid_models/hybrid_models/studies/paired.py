"""
Two models of one study compared seed by seed: an order between them, or a tie.

In a study (``offline/crossval.py``, ``offline/workflow.py``) every model is trained with
the same seeds on the same folds and validation runs, so seed k of one is paired with
seed k of the other. For the position error at the horizon's end and the trajectory
error over the horizon, each pooled over the study's test forecasts as in its table
(m), the comparison gives each seed's pair, how many seeds have the first model ahead,
the mean paired difference (first - second) with its standard error over seeds, and a
paired t-test and a sign test (scipy): whether the seeds support an order or only a tie.
"""

from __future__ import annotations

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


def paired_rows(first: dict, second: dict) -> dict:
    """
    Compare two rows of a study's results.json seed by seed; {metric name: ``compare``}.

    Raises ValueError when a row has no per-seed figures or the seed counts differ.
    """
    seeds = [len(row.get('per_seed_metrics') or []) for row in (first, second)]
    if not all(seeds) or seeds[0] != seeds[1]:
        raise ValueError(f"rows {first['label']!r} and {second['label']!r} have "
                         f'{seeds[0]} and {seeds[1]} seeds: no pairs to compare')
    return {name: compare(per_seed(first, key), per_seed(second, key))
            for name, key in METRICS.items()}


def paired_table(result: dict) -> list[str]:
    """Return the Markdown table of a ``paired_rows`` result, one line per metric."""
    lines = ['| error | per seed (first / second) | first ahead | mean difference ± se '
             '| paired t-test p | sign test p |', '|---|---|---|---|---|---|']
    for name, c in result.items():
        pairs = ', '.join(f'{a:.2f} / {b:.2f}' for a, b in zip(c['first'], c['second'],
                                                                 strict=True))
        se, p = c['standard_error'], c['t_test_p']   # None with a single seed
        lines.append(f"| {name} | {pairs} | {c['first_ahead']} of {c['seeds']} | "
                     f"{c['mean_difference']:+.3f} ± {'–' if se is None else f'{se:.3f}'} | "
                     f"{'–' if p is None else f'{p:.2f}'} | {c['sign_test_p']:.2f} |")
    return lines
