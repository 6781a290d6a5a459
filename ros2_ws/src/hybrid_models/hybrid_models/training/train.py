"""
Train one model from a resolved config: data, physics fit, statistics, fit loop.

``train(cfg, out_dir)`` writes into ``out_dir``: ``model.safetensors`` (the best
model by validation multistep error, with every figure of its config), ``best`` and
``last`` checkpoints, ``log.jsonl`` (one line per epoch) and ``config.yaml``.
Under torchrun every rank calls ``train`` and trains its share
(``hybrid_models.training.distributed``); only rank 0 writes those files.
"""

from __future__ import annotations

import math
from pathlib import Path
import sys
import time

import numpy as np
import torch
import yaml

from hybrid_models.bound import output_range
from hybrid_models.checkpoint import load_checkpoint, save_checkpoint
from hybrid_models.data import dataset_hash, forecast_windows, load_runs, one_step_pairs
from hybrid_models.metrics import normalized_rmse_sum
from hybrid_models.models import build_model, predict
from hybrid_models.nets import HybridModel
from hybrid_models.normalization import Normalizer
from hybrid_models.physical import CompositeModel, RegressionModel
from hybrid_models.training.config import fill_from_vessel
from hybrid_models.training.distributed import Group, join, leave
from hybrid_models.training.loop import BEST, LAST, LoopState, fit
from hybrid_models.training.tasks import RecurrentTask
from hybrid_models.vehicle import VehicleSpec, load_vessel
from vessel_datasets.format import read_dataset

MODEL_FILE = 'model.safetensors'


def dataset_vessel(cfg: dict) -> VehicleSpec:
    """Return the vessel of the config's dataset, checked against the config's vessel file."""
    vessel = read_dataset(cfg['dataset']).vessel
    if cfg.get('vessel'):
        load_vessel(cfg['vessel']).check_compatible(vessel, f'dataset {cfg["dataset"]}')
    return vessel


def check_windows(cfg: dict, spec: VehicleSpec) -> None:
    """Refuse, before any training, a split that cannot give a single forecast window."""
    t, e = cfg['training'], cfg['evaluation']
    needs = {'train': t['window'] + t['sequence_length'],
             'val': t['window'] + t['validation']['horizon'],
             'test': t['window'] + e['horizon']}
    runs = read_dataset(cfg['dataset']).manifest['runs']
    for split, need in needs.items():
        lengths = [r['n_samples'] for r in runs if r['split'] == split]
        if split == 'test' and not lengths:
            continue  # a dataset kept whole for training and validation
        longest = max(lengths, default=0)
        if longest < need:
            raise ValueError(
                f'no {split} run is long enough: the longest has {longest} samples '
                f'({longest * spec.dt:.1f} s), a forecast window needs {need} '
                f'({need * spec.dt:.1f} s at {spec.rate_hz:g} Hz); shorten the window or '
                f'horizon (vessel file or training config) or use longer runs')


def train(cfg: dict, out_dir: str | Path, resume: bool = False, device: str = 'auto') -> dict:
    """
    Train the configured model; returns the final checkpoint's config.

    ``device``: auto (a GPU when one is present), cpu or cuda. Launched by torchrun,
    this process joins the job's process group for the duration of the call.
    """
    if cfg['dataset'] is None:
        raise ValueError('the config names no dataset (key "dataset" or --dataset)')
    # Everything that can refuse the dataset runs before anything is written.
    spec = dataset_vessel(cfg)
    cfg = fill_from_vessel(cfg, spec)
    check_windows(cfg, spec)
    group = join(device)
    try:
        return _train(cfg, spec, Path(out_dir), resume, group)
    finally:
        leave(group)


def _train(cfg: dict, spec: VehicleSpec, out_dir: Path, resume: bool, group: Group) -> dict:
    tcfg = cfg['training']
    torch.set_num_threads(int(tcfg['threads']))
    torch.manual_seed(tcfg['seed'])
    if group.main:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / 'config.yaml').write_text(yaml.safe_dump(cfg, sort_keys=False))
    t_start = time.monotonic()
    train_runs = load_runs(cfg['dataset'], 'train', spec)
    val_runs = load_runs(cfg['dataset'], 'val', spec)
    base = {'dataset': {'path': str(cfg['dataset']), 'sha256': dataset_hash(cfg['dataset']),
                        'train_runs': [r.run_id for r in train_runs],
                        'val_runs': [r.run_id for r in val_runs]},
            'vehicle': spec.to_dict(), 'training': cfg, 'name': cfg['name']}
    z, c, _ = one_step_pairs(train_runs)
    state_norm, control_norm = Normalizer.fit(z), Normalizer.fit(c)
    base['normalization'] = {'state': state_norm.to_dict(), 'control': control_norm.to_dict()}
    kind = cfg['model']['kind']
    if kind == 'qlag':
        # A closed-form fit: nothing to share out; every rank fits, rank 0 writes.
        model, extra = _fit_qlag(cfg, spec, train_runs, val_runs, state_norm)
        summary = {**base, **extra, 'model': model.describe()}
        if group.main:
            save_checkpoint(out_dir / MODEL_FILE, model, summary)
        return summary
    model = build_model(cfg['model'], spec)
    model.set_normalization(state_norm, control_norm)
    z_phy_train = z_phy_val = None
    if isinstance(model, HybridModel):
        z_phy_train, z_phy_val, phys_info = _prepare_physics(model, cfg, train_runs, val_runs)
        base.update(phys_info)
    model.to(group.device)
    task = RecurrentTask(train_runs, val_runs, tcfg, state_norm.std, z_phy_train, z_phy_val,
                         device=group.device)
    base['parameters'] = sum(p.numel() for p in model.parameters())

    def checkpoint_config() -> dict:
        return {**base, 'model': model.describe()}

    resume = resume and (out_dir / LAST).exists()
    state: LoopState = fit(model, task, tcfg, out_dir, checkpoint_config, resume=resume,
                           group=group)
    if not group.main:
        return {**checkpoint_config(), 'epochs': state.epoch, 'rank': group.rank}
    best = load_checkpoint(out_dir / BEST if (out_dir / BEST).exists() else out_dir / LAST)
    model.load_state_dict(best.model_state)
    summary = {**checkpoint_config(), 'val': best.config.get('val'),
               'best_epoch': state.best_epoch, 'epochs': state.epoch,
               'bad_steps': state.bad_steps, 'rollbacks': state.rollbacks,
               'stop_reason': state.stop_reason,
               'train_seconds': round(state.elapsed_s, 1),
               'wall_seconds_this_session': round(time.monotonic() - t_start, 1)}
    save_checkpoint(out_dir / MODEL_FILE, model, summary)
    return summary


def _fit_qlag(cfg, spec, train_runs, val_runs, state_norm):
    """Fit QLag for each candidate lag; keep the best on validation multistep error."""
    tcfg = cfg['training']
    windows = forecast_windows(val_runs, tcfg['window'], tcfg['validation']['horizon'],
                               tcfg['validation']['stride'])
    scores, best = {}, None
    for lag in cfg['model']['lags']:
        model = build_model({**cfg['model'], 'lag': lag}, spec).fit(train_runs)
        score = normalized_rmse_sum(predict(model, windows), windows.z_target, state_norm.std)
        scores[int(lag)] = score if math.isfinite(score) else None
        print(f'qlag lag {lag}: val score {score:.4g}', file=sys.stderr)
        if best is None or score < best[0]:
            best = (score, model)
    return best[1], {'val': {'score': best[0]}, 'lag_scores': scores}


def _prepare_physics(model: HybridModel, cfg, train_runs, val_runs):
    """Fit the regression part, compute the output range, residual scale and bound."""
    physical = model.physical
    z, c, z_next = one_step_pairs(train_runs)
    physical.fit(z, c, z_next)
    z_phy_train = [physical.predict(r.z[:-1], r.c[:-1]) for r in train_runs]
    z_phy_val = [physical.predict(r.z[:-1], r.c[:-1]) for r in val_runs]
    one_step = np.concatenate(z_phy_train)
    residual = z_next - one_step
    res_norm = Normalizer.fit(residual)
    model.residual_std.copy_(torch.as_tensor(res_norm.std))
    # The 95 % range is taken over training AND validation one-step outputs (paper).
    r95 = output_range(np.concatenate([one_step] + z_phy_val))
    model.output_range.copy_(torch.as_tensor(r95))
    model.set_threshold(cfg['model']['relative_threshold'])
    one_step_rmse = np.sqrt((residual ** 2).mean(axis=0))
    info = {'physics': _physics_info(physical),
            'bound': {'definition': 'b_i = T * R_i / 2, R_i = q97.5 - q2.5 of one-step '
                                    'physical outputs on train+val',
                      'output_range': r95.tolist(),
                      'relative_threshold': cfg['model']['relative_threshold'],
                      'half_width': model.bound.tolist()},
            'physics_one_step_rmse': dict(zip(model.spec.state_names,
                                              one_step_rmse.tolist(), strict=True))}
    return z_phy_train, z_phy_val, info


def _physics_info(physical) -> dict:
    """Human-readable physics: description, fitted coefficients, parameter YAML."""
    info = {'describe': physical.describe()}
    parts = [physical] if not isinstance(physical, CompositeModel) else [
        physical.first_principles, physical.regression]
    for part in parts:
        if isinstance(part, RegressionModel):
            info['regression_coefficients'] = part.coefficients()
        elif hasattr(part, 'params_yaml'):
            info['params_yaml'] = part.params_yaml
    return info
