r"""
Write the relative threshold a hybrid checkpoint is served with into the checkpoint.

A hybrid's or an ensemble's (``hybrid_models.ensemble``: one threshold for every member).

    set_threshold MODEL.safetensors 0.15              # in place
    set_threshold MODEL.safetensors none --out B.safetensors

T bounds the LSTM's correction to T R / 2 per state (R: the physical model's 95 %
output range, stored in the checkpoint); 'none' leaves it unbounded and 0 keeps the
physics alone (``hybrid_models.bound``). The predictor and
``Forecaster.from_checkpoint`` serve this threshold unless told another; the weights
are not touched (only the bound buffer and the config's threshold change).
"""

import argparse
from pathlib import Path
import sys

from hybrid_models.checkpoint import CheckpointError, load_hybrid, save_checkpoint
from hybrid_models.cli.arguments import threshold


def set_threshold(path: Path, relative_threshold: float | None, out: Path) -> dict:
    """Rewrite ``path`` to ``out`` with the threshold; return its bound section."""
    model, config = load_hybrid(path, 'a bound')
    model.set_threshold(relative_threshold)
    bound = {**config.get('bound', {}), 'relative_threshold': relative_threshold,
             'half_width': model.bound.tolist()}
    save_checkpoint(out, model, {**config, 'model': model.describe(), 'bound': bound})
    return bound


def main(argv=None) -> int:
    """Parse arguments and rewrite the checkpoint; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoint', type=Path, help='hybrid checkpoint (.safetensors)')
    parser.add_argument('threshold', type=threshold, help="relative threshold T, or 'none'")
    parser.add_argument('--out', type=Path, help='write here instead of in place')
    args = parser.parse_args(argv)
    try:
        bound = set_threshold(args.checkpoint, args.threshold, args.out or args.checkpoint)
    except (CheckpointError, FileNotFoundError, ValueError) as exc:
        print(f'set_threshold: error: {exc}', file=sys.stderr)
        return 2
    print(f'set_threshold: {args.out or args.checkpoint}: relative threshold '
          f'{args.threshold}, half-widths {[round(b, 6) for b in bound["half_width"]]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
