r"""
Train one forecasting model (QLag, LSTM or hybrid) from a YAML config.

    python offline/train.py ros2_ws/src/hybrid_models/config/smoke.yaml \\
        --dataset DIR --out runs/smoke
    python offline/train.py CONFIG --out runs/x --resume     # continue a killed run
    python offline/train.py CONFIG --set model.physical.kind=min+lin --set training.seed=1
    torchrun --nproc_per_node=2 offline/train.py CONFIG --out runs/x   # data-parallel

Runs as one process, or unchanged under torchrun (DistributedDataParallel, gloo on
CPU, NCCL on GPUs); training.batch_size is the global batch whatever the number of
processes (README, "Scaling out").

Writes into --out: model.safetensors (best model by validation multistep error),
best/last checkpoints, log.jsonl (one line per epoch), config.yaml. Progress bars and
per-epoch lines go to stderr; the final summary (JSON) to stdout.
"""

import argparse
import json
from pathlib import Path
import sys

from hybrid_models.training import ConfigError, load_config, train
from hybrid_models.training.distributed import DEVICES
from hybrid_models.training.jobs import die_with_parent


def main(argv=None) -> int:
    """Parse arguments, train, print the summary; return the exit code."""
    die_with_parent()
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('config', type=Path, help='YAML training config')
    parser.add_argument('--dataset', help='dataset directory (overrides the config)')
    parser.add_argument('--out', type=Path,
                        help='output directory (default runs/<name> in the working directory)')
    parser.add_argument('--resume', action='store_true',
                        help='continue from OUT/last.safetensors if it exists')
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='override a config value, e.g. training.seed=1 (repeatable)')
    parser.add_argument('--quiet', action='store_true', help='no progress bars')
    parser.add_argument('--device', choices=DEVICES, default='auto',
                        help='auto (a GPU when one is present), cpu or cuda (default auto)')
    args = parser.parse_args(argv)
    overrides = list(args.set)
    if args.dataset:
        overrides.append(f'dataset={args.dataset}')
    if args.quiet:
        overrides.append('training.progress=false')
    try:
        cfg = load_config(args.config, overrides)
        out = args.out or Path('runs') / cfg['name']
        summary = train(cfg, out, resume=args.resume, device=args.device)
    except (ConfigError, ValueError, FileNotFoundError) as exc:
        print(f'train.py: error: {exc}', file=sys.stderr)
        return 2
    if summary.get('rank', 0) != 0:
        return 0  # rank 0 reports for the whole job
    keep = ('name', 'val', 'best_epoch', 'epochs', 'train_seconds', 'stop_reason',
            'bad_steps', 'rollbacks', 'parameters')
    print(json.dumps({k: summary.get(k) for k in keep} | {'out': str(out)}, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
