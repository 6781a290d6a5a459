"""
What do-no-harm's fallbacks cost: serve each fallen-back training at its best candidate.

Usage:  tools/with_env.sh python docs/results/real/analysis/serve_best_candidate.py RUNS
RUNS is a model's folder of trainings in a study (e.g. STUDY/runs/hybrid_on_augmented_
physics, with fold*/seed*/model.safetensors). Run it on a copy: it rewrites checkpoints.

With one validation run, ``hybrid_models.selection`` counts any worse mean at a reported
step as harm, and a training whose every threshold is worse somewhere on that run is
served as its physics alone. This post hoc check serves each such training at the
threshold of the lowest validation score among its whole-forecast candidates instead,
harm ignored (``set_threshold`` of ``offline/set_threshold.py``; weights untouched), so
that the study pooled again says what the fallbacks cost on the held-out runs. A
training whose epochs all lost to the physics (no candidates) stays as it is. Prints one
Markdown row per training changed, and the count of those left.
"""

from __future__ import annotations

from pathlib import Path
import sys

from hybrid_models.checkpoint import read_header
from hybrid_models.cli.set_threshold import set_threshold


def main(argv: list[str]) -> int:
    """Re-serve every fallen-back training under RUNS; print what changed."""
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    print('| training | served | now | its validation score | physics alone | harm found |')
    print('|---|---|---|---|---|---|')
    left = 0
    for path in sorted(Path(argv[0]).glob('fold*/seed*/model.safetensors')):
        selection = read_header(path).get('selection')
        if selection is None or selection['relative_threshold'] != 0.0:
            continue
        whole = [c for c in selection['candidates'] if c['from_s'] == 0.0]
        if not whole:
            left += 1
            continue
        best = min(whole, key=lambda c: c['score'])
        set_threshold(path, best['relative_threshold'], path)
        name = '/'.join(path.parts[-3:-1])
        print(f"| {name} | 0 (physics alone) | {best['relative_threshold']} | "
              f"{best['score']:.4f} | {selection['physics']['score']:.4f} | "
              f"{', '.join(best['harms'])} |")
    print(f'\n{left} fallen-back training(s) without candidates left as they were.')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
