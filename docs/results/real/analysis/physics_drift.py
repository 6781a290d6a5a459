"""
What the multistep training phase sees of each physics: its loss alone against the hybrid's.

Usage:  tools/with_env.sh python docs/results/real/analysis/physics_drift.py STUDY OUT
STUDY is the --out folder of ``offline/workflow.py --folds K``; OUT receives drift.md and
drift.json.

For every fold and physics (nominal, augmented) of the study: the normalized state MSE
of the physics alone, free-running from measured states over 1 to 400 steps, on the
fold's training runs (windows every 5 s; the training's own normalization), which at the
multistep phase's sequence length is where the hybrid's training loss starts (its
correction starts at zero); and, from each seed's training log, the multistep training
loss at the multistep epoch of best validation score and at the last epoch, with the
epoch the checkpoint kept (``best_epoch``: a teacher-phase epoch where one scored
better than every multistep epoch). Dropout is on in the training loss, off in the
physics' loss.
"""

from __future__ import annotations

import json
from pathlib import Path
import sys

import numpy as np
from workflow_folds import open_study

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.models import predict
from hybrid_models.studies.crossval import run_dir
from hybrid_models.training.train import MODEL_FILE

LENGTHS = (1, 10, 25, 50, 100, 200, 400)   # steps
WINDOW_STRIDE_S = 5.0


def physics_loss(physical, runs, window: int, length: int, stride: int,
                 std: np.ndarray) -> float:
    """Return the normalized MSE of the physics alone, ``length`` steps from measured states."""
    usable = [r for r in runs if r.length >= window + length]
    windows = forecast_windows(usable, window, length, stride, 'true')
    pred = predict(PhysicsOnly(physical), windows)
    return float((((pred - windows.z_target) / std) ** 2).mean())


def training_losses(log: Path) -> tuple[float, float, bool]:
    """
    Return the multistep training loss at its best-scored epoch and at the last.

    And whether that epoch is the one kept (``best_epoch`` of the run's checkpoint).
    """
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    multistep = [r for r in rows if r.get('phase_kind') == 'multistep']
    best = min(multistep, key=lambda r: r['val_score'])
    kept = load_model(log.with_name(MODEL_FILE))[1]['best_epoch']
    return best['train_loss'], multistep[-1]['train_loss'], best['epoch'] == kept


def main(argv: list[str]) -> int:
    """Compute, print and write the table."""
    if len(argv) != 2:
        print(__doc__.split('\n\n')[1], file=sys.stderr)
        return 2
    study, out = Path(argv[0]), Path(argv[1])
    folds, _protocol, spec, hybrids = open_study(study)
    rows = []
    for fold in folds:
        runs = load_runs(fold.path, 'train', spec)
        for label in hybrids:
            seeds = sorted(int(p.name[4:]) for p in run_dir(study, label, fold, 0).parent.glob(
                'seed*'))
            model, config = load_model(run_dir(study, label, fold, seeds[0]) / MODEL_FILE)
            std = np.asarray(config['normalization']['state']['std'], np.float64)
            window = int(config['training']['training']['window'])
            sequence = int(config['training']['training']['sequence_length'])
            stride = int(round(WINDOW_STRIDE_S / spec.dt))
            alone = {n: physics_loss(model.physical, runs, window, n, stride, std)
                     for n in sorted({*LENGTHS, sequence})}
            losses = [training_losses(run_dir(study, label, fold, s) / 'log.jsonl')
                      for s in seeds]
            rows.append({'fold': fold.index, 'model': label, 'sequence_length': sequence,
                         'physics_alone': alone,
                         'best_multistep_train_loss': [b for b, _, _ in losses],
                         'last_train_loss': [last for _, last, _ in losses],
                         'best_multistep_epoch_kept': [k for _, _, k in losses]})
            print(f'fold {fold.index} {label}: alone at {sequence} steps '
                  f'{alone[sequence]:.2e}, best multistep '
                  f'{np.mean(rows[-1]["best_multistep_train_loss"]):.2e}',
                  file=sys.stderr, flush=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'drift.json').write_text(json.dumps(rows, indent=1))
    lines = ['| fold | model | ' + ' | '.join(f'alone, {n} steps' for n in LENGTHS)
             + ' | hybrid, best multistep epoch (train) | hybrid, last epoch (train) '
             '| kept a multistep epoch |',
             '|---' * (len(LENGTHS) + 5) + '|']
    for row in rows:
        alone = row['physics_alone']
        lines.append(f"| {row['fold']} | {row['model']} | "
                     + ' | '.join(f'{alone[n]:.2e}' for n in LENGTHS)
                     + f" | {np.mean(row['best_multistep_train_loss']):.2e} ± "
                       f"{np.std(row['best_multistep_train_loss']):.1e}"
                     + f" | {np.mean(row['last_train_loss']):.2e}"
                     + f" | {sum(row['best_multistep_epoch_kept'])} of "
                       f"{len(row['best_multistep_epoch_kept'])} |")
    text = '\n'.join(lines) + '\n'
    (out / 'drift.md').write_text(text)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
