"""
The smallest relative threshold that keeps a hybrid within 5 % of its unconstrained error.

Usage:  python docs/results/real/analysis/threshold_needed.py RESULTS.json [...]
Each RESULTS.json is an offline/evaluate.py output with a threshold sweep; prints a
Markdown table: per swept hybrid, the unconstrained trajectory error and the smallest
threshold whose mean trajectory error is at most 1.05 times it.
"""

import json
import sys

TOLERANCE = 1.05


def needed(sweep: dict) -> tuple[float, float | None, float | None]:
    """Return (unconstrained error, smallest threshold within tolerance, its error)."""
    rows = sweep['rows']
    free = next(r for r in rows if r['relative_threshold'] is None)['trajectory']['mean']
    bounded = sorted((r for r in rows if r['relative_threshold'] is not None),
                     key=lambda r: r['relative_threshold'])
    for row in bounded:
        if row['trajectory']['mean'] <= TOLERANCE * free:
            return free, row['relative_threshold'], row['trajectory']['mean']
    return free, None, None


def main(paths) -> int:
    """Print the table for every results file given."""
    if not paths:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    print('| hybrid | unconstrained trajectory error [m] | smallest threshold within 5 % '
          '| its error [m] |')
    print('|---|---|---|---|')
    for path in paths:
        with open(path) as f:
            sweep = json.load(f).get('threshold_sweep')
        if not sweep:
            continue
        free, threshold, error = needed(sweep)
        print(f'| {sweep["label"]} | {free:.3f} | '
              f'{"none of those tried" if threshold is None else threshold} | '
              f'{"" if error is None else f"{error:.3f}"} |')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
