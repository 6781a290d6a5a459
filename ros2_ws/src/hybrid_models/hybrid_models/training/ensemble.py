"""
Serve trained hybrids of one config as one ensemble (``hybrid_models.ensemble``).

``serve_ensemble(members, dataset, out)`` packs member checkpoints, trained with
different seeds on the same dataset, into one checkpoint: their ensemble is served at
the relative threshold its own validation forecasts choose (the do-no-harm selection
of a single hybrid, ``train.select_threshold``) with bands calibrated on the same
forecasts (``train.calibrate_bands``). The validation runs are the members' own: the
dataset must be the one they were trained on (its hash), else it is refused in one line.
``hybrid_models.training.train`` calls ``train_ensemble`` when ``training.members`` asks
for more than one:
member i is trained with seed ``training.seed + i`` into ``OUT/members/member<i>``
(a finished member is kept by ``--resume``), then the ensemble is written to
``OUT/model.safetensors``.
"""

from __future__ import annotations

from collections.abc import Sequence
import copy
import os
from pathlib import Path
import sys

import numpy as np

from hybrid_models.checkpoint import load_model, save_checkpoint
from hybrid_models.data import dataset_hash, load_runs
from hybrid_models.ensemble import EnsembleError, pack
from hybrid_models.training.config import ConfigError
from hybrid_models.training.loop import REFERENCE_EPOCH
from hybrid_models.training.tasks import RecurrentTask
from hybrid_models.training.train import (
    MODEL_FILE,
    calibrate_bands,
    select_threshold,
    train_model,
)
from vessel_datasets.format import read_dataset


def serve_ensemble(members: Sequence[str | Path], dataset: str | Path, out: str | Path
                   ) -> dict:
    """Pack ``members`` (checkpoint paths), select and calibrate; write ``out``; its config."""
    loaded = [load_model(path) for path in members]
    configs = [config for _, config in loaded]
    ensemble = pack([model for model, _ in loaded])
    ds = read_dataset(dataset)
    trained_on = {c['dataset']['sha256'] for c in configs}
    if len(trained_on) > 1:
        raise EnsembleError('the members were trained on different datasets: an ensemble '
                            'is chosen on the validation runs they share')
    if dataset_hash(ds) not in trained_on:
        raise EnsembleError(f'{dataset} is not the dataset the members were trained on '
                            f"({configs[0]['dataset']['path']}): its validation runs must "
                            f'choose the ensemble')
    spec = ensemble.spec
    val_ids = configs[0]['dataset']['val_runs']
    val = [r for r in load_runs(ds, 'val', spec) if r.run_id in val_ids]
    tcfg = configs[0]['training']['training']
    state_std = np.asarray(configs[0]['normalization']['state']['std'], np.float64)
    task = RecurrentTask(spec, [], val, tcfg, state_std)
    best = max(int(c.get('best_epoch', 0)) for c in configs)
    # The configured threshold caps the choice, as for one hybrid (not a member's choice).
    ensemble.set_threshold(configs[0]['training']['model']['relative_threshold'])
    selection = (select_threshold(ensemble, task, tcfg, best)
                 if tcfg['selection']['do_no_harm'] else None)
    summary = {**configs[0], 'model': ensemble.describe(),
               'bound': {**configs[0].get('bound', {}),
                         'relative_threshold': ensemble.relative_threshold,
                         'half_width': ensemble.bound.tolist()},
               'selection': selection,
               'bands': calibrate_bands(ensemble, task, tcfg),
               'best_epoch': None if best == REFERENCE_EPOCH else best,
               'ensemble': {'members': [str(p) for p in members],
                            'seeds': [c['training']['training']['seed'] for c in configs],
                            'member_val': [c.get('val') for c in configs]}}
    save_checkpoint(out, ensemble, summary)
    return summary


def train_ensemble(cfg: dict, out: Path, resume: bool = False, device: str = 'auto') -> dict:
    """Train ``training.members`` hybrids of ``cfg`` (seeds seed, seed + 1, ...), serve them."""
    count = int(cfg['training']['members'])
    if cfg['model']['kind'] != 'hybrid':
        raise ConfigError(f"training.members: {count} members form an ensemble of hybrids; "
                          f"a {cfg['model']['kind']} is trained alone (members: 1)")
    paths, seconds = [], 0.0
    for i in range(count):
        member = copy.deepcopy(cfg)
        member['training'].update(members=1, seed=cfg['training']['seed'] + i)
        member_out = out / 'members' / f'member{i}'
        if not (resume and (member_out / MODEL_FILE).is_file()):
            seconds += train_model(member, member_out, resume=resume, device=device).get(
                'train_seconds') or 0.0
        paths.append(member_out / MODEL_FILE)
        print(f"member {i + 1}/{count} trained (seed {member['training']['seed']})",
              file=sys.stderr)
    if int(os.environ.get('RANK', '0')) != 0:
        return {'rank': int(os.environ['RANK'])}   # rank 0 packs and writes
    summary = serve_ensemble(paths, cfg['dataset'], out / MODEL_FILE)
    selection = summary.get('selection') or {}
    return {**summary, 'val': {'score': selection.get('score')}, 'train_seconds': seconds,
            'epochs': None, 'stop_reason': f'{count} members trained'}
