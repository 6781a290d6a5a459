r"""
Turn a hybrid checkpoint's novelty fade on or off: a bound that fades off its training data.

    set_novelty MODEL.safetensors on                 # in place
    set_novelty MODEL.safetensors off --out B.safetensors

Served with the fade, the correction's bound is scaled at every step by the share
available, min(1, r / d): d is how far the correction's input lies from the training
runs' inputs (RMS Mahalanobis distance), r the farthest of the training and validation
runs' inputs (``hybrid_models.novelty``). Inside what training and validation covered
the bound is the plain one; twice as far out, half of it. Training calibrates every
hybrid it makes, so this only turns the fade on or off (a checkpoint trained before has
no calibration and is refused: train it again); weights, threshold and bands are kept.
The predictor reports the share each forecast step had (Forecast.bound_available).
"""

import argparse
from pathlib import Path
import sys

from hybrid_models import novelty
from hybrid_models.checkpoint import CheckpointError, load_hybrid, save_checkpoint

SETTINGS = {'on': True, 'off': False}


def set_novelty(path: Path, fade: bool, out: Path) -> list[float]:
    """Rewrite ``path`` to ``out`` served with the fade or without; return the radii."""
    model, config = load_hybrid(path, 'a bound to fade')
    members = novelty.hybrids_of(model)
    if any(m.novelty is None for m in members):
        raise CheckpointError(f'{path}: the checkpoint holds no novelty calibration (it was '
                              f'trained before hybrids were calibrated): train it again')
    for m in members:
        m.novelty_fade = fade
    save_checkpoint(out, model, {**config, 'model': model.describe()})
    return [m.novelty.radius for m in members]


def main(argv=None) -> int:
    """Parse arguments and rewrite the checkpoint; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoint', type=Path, help='hybrid checkpoint (.safetensors)')
    parser.add_argument('fade', choices=sorted(SETTINGS), help='serve the fade, or not')
    parser.add_argument('--out', type=Path, help='write here instead of in place')
    args = parser.parse_args(argv)
    try:
        radii = set_novelty(args.checkpoint, SETTINGS[args.fade], args.out or args.checkpoint)
    except (CheckpointError, FileNotFoundError, ValueError) as exc:
        print(f'set_novelty: error: {exc}', file=sys.stderr)
        return 2
    print(f'set_novelty: {args.out or args.checkpoint}: novelty fade {args.fade} (radius '
          f'{", ".join(f"{r:.3g}" for r in radii)})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
