r"""
Serve trained hybrids of one config (seeds) as one ensemble checkpoint.

    python offline/ensemble.py runs/seed0/model.safetensors runs/seed1/model.safetensors \
        runs/seed2/model.safetensors --dataset data/boat --out runs/ensemble.safetensors
    ros2 run hybrid_models ensemble ...          # the same program, installed

Each step of the ensemble adds the mean of the members' bounded corrections to their
one physics (``hybrid_models.ensemble``), so it is still the physics plus a known
amount. The members must share vessel, physics, architecture and the dataset they were
trained on (given with --dataset): its validation runs choose the ensemble's relative
threshold (do no harm, as for one hybrid) and calibrate its bands. ``training.members:
K`` in a training config trains the members and does this in one go.

Prints the served threshold and why. Exit status: 0 written, 2 on bad input (one line).
"""

import argparse
from pathlib import Path
import sys

from hybrid_models.checkpoint import CheckpointError
from hybrid_models.training.ensemble import serve_ensemble
from vessel_datasets.format import DatasetError


def main(argv=None) -> int:
    """Parse arguments, pack, select, write; return the exit code."""
    parser = argparse.ArgumentParser(prog='ensemble', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('members', nargs='+', type=Path,
                        help='hybrid checkpoints of one config (e.g. one per seed)')
    parser.add_argument('--dataset', required=True, type=Path,
                        help='the dataset the members were trained on')
    parser.add_argument('--out', required=True, type=Path, help='ensemble checkpoint to write')
    args = parser.parse_args(argv)
    try:
        summary = serve_ensemble(args.members, args.dataset, args.out)
    except (CheckpointError, DatasetError, ValueError, FileNotFoundError) as exc:
        print(f'ensemble: error: {exc}', file=sys.stderr)
        return 2
    selection = summary.get('selection') or {}
    print(f"ensemble: {args.out}: {len(args.members)} members, relative threshold "
          f"{summary['bound']['relative_threshold']}"
          + (f" ({selection['reason']})" if selection.get('reason') else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
