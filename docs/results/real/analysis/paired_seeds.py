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
the script prints the comparison of ``hybrid_models.studies.paired`` (which the workflow's
report also holds): an order, or a tie.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

from hybrid_models.studies.paired import paired_rows, paired_table


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
    try:
        result = paired_rows(first, second)
    except ValueError as exc:
        parser.error(str(exc))
    lines = [f'# {args.first} against {args.second}, seed by seed', '',
             f'Study `{args.study.name}`; seed k of one is paired with seed k of the other '
             '(same folds, validation runs and seed).', '', *paired_table(result)]
    text = '\n'.join(lines) + '\n'
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'paired.json').write_text(json.dumps(result, indent=2))
    (args.out / 'paired.md').write_text(text)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
