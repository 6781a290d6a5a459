"""
Train one model from a resolved config: data, physics fit, statistics, fit loop.

``train_model(cfg, out_dir)`` writes into ``out_dir``: ``model.safetensors`` (the best
model by validation multistep error, with every figure of its config; a hybrid served
at the relative threshold its validation runs chose, ``select_threshold``), ``best`` and
``last`` checkpoints, ``log.jsonl`` (one line per epoch) and ``config.yaml``.
Under torchrun every rank calls ``train_model`` and trains its share
(``hybrid_models.training.distributed``); only rank 0 writes those files.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np
import torch
import yaml

from hybrid_models import novelty
from hybrid_models.bands import BandsError, calibrate
from hybrid_models.bound import output_range
from hybrid_models.checkpoint import load_checkpoint, save_checkpoint
from hybrid_models.data import dataset_hash, forecast_windows, load_runs
from hybrid_models.hybrid_step import correction_input
from hybrid_models.metrics import normalized_rmse_sum
from hybrid_models.models import build_model, predict
from hybrid_models.nets import HybridModel
from hybrid_models.physical import CompositeModel, RegressionModel
from hybrid_models.physical.envelope import envelope_escapes, escape_warning
from hybrid_models.run_store import RowFile, RowWriter, build_split
from hybrid_models.selection import (
    PHYSICS_ALONE,
    choose_schedule,
    forecast_figures,
    threshold_grid,
)
from hybrid_models.streaming import Moments, RowSample
from hybrid_models.training.config import fill_from_vessel
from hybrid_models.training.distributed import Group, join, leave
from hybrid_models.training.loop import BEST, LAST, REFERENCE_EPOCH, LoopState, fit
from hybrid_models.training.tasks import RecurrentTask
from vessel_datasets.format import Dataset, read_dataset
from vessel_description import Vessel, load_vessel

MODEL_FILE = 'model.safetensors'


def dataset_vessel(cfg: dict, ds: Dataset) -> Vessel:
    """
    Return the vessel of the dataset, or the config's vessel file when it names one.

    The file must have the dataset's vectors and rate; what else it says (its mirror
    image, its limits) may be newer than the dataset's copy, and wins.
    """
    vessel = ds.vessel
    if cfg.get('vessel'):
        given = load_vessel(cfg['vessel'])
        given.check_compatible(vessel, f'dataset {cfg["dataset"]}')
        return given
    return vessel


def uses_mirror(setting, spec: Vessel) -> bool:
    """
    Tell whether training adds the mirror images of the training runs.

    'auto': when the vessel file declares its mirror image (a symmetric vessel); true:
    always, refused for a vessel that declares none; false: never.
    """
    if setting == 'auto':
        return spec.mirror is not None
    if setting is True and spec.mirror is None:
        spec.mirror_maps()   # raises: the vessel file declares no mirror image
    if not isinstance(setting, bool):
        raise ValueError(f'training.mirror must be auto, true or false, got {setting!r}')
    return setting


def check_windows(cfg: dict, spec: Vessel, ds: Dataset) -> None:
    """Refuse, before any training, a split that cannot give a single forecast window."""
    t, e = cfg['training'], cfg['evaluation']
    needs = {'train': t['window'] + t['sequence_length'],
             'val': t['window'] + t['validation']['horizon'],
             'test': t['window'] + e['horizon']}
    runs = ds.manifest['runs']
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


def train_model(cfg: dict, out_dir: str | Path, resume: bool = False,
                device: str = 'auto') -> dict:
    """
    Train the configured model; returns the final checkpoint's config.

    One model: ``training.members`` above 1 (an ensemble) is ``hybrid_models.training.
    train``'s. ``device``: auto (a GPU when one is present), cpu or cuda. Launched by
    torchrun, this process joins the job's process group for the duration of the call.
    """
    if cfg['dataset'] is None:
        raise ValueError('the config names no dataset (key "dataset" or --dataset)')
    if cfg['training']['members'] > 1:
        raise ValueError(f"train_model trains one model, the config asks for "
                         f"{cfg['training']['members']} members: use "
                         f"hybrid_models.training.train")
    # Everything that can refuse the dataset runs before anything is written.
    ds = read_dataset(cfg['dataset'])
    spec = dataset_vessel(cfg, ds)
    cfg = fill_from_vessel(cfg, spec)
    check_windows(cfg, spec, ds)
    uses_mirror(cfg['training']['mirror'], spec)
    group = join(device)
    try:
        return _train(cfg, spec, ds, Path(out_dir), resume, group)
    finally:
        leave(group)


# The recurrent layers a warm start copies (nets.HybridModel); the head is left as it is.
WARM_START_LAYERS = ('init.', 'lstm.')


def warm_start(model, path: Path) -> dict:
    """
    Copy the recurrent layers of the hybrid checkpoint ``path`` into ``model``.

    Refused (ValueError, one line) unless ``model`` is a hybrid and the checkpoint holds
    every such layer with the same cell and shape. Return what was copied, for the
    checkpoint.
    """
    if not isinstance(model, HybridModel):
        raise ValueError(f'training.init_from: only a hybrid starts from another, not a '
                         f'{model.kind}')
    checkpoint = load_checkpoint(path)
    described = checkpoint.config.get('model') or {}
    # Checkpoints older than the key 'cell' were LSTMs.
    cell = described.get('member', described).get('cell', 'lstm')
    if cell != model.cell.name:
        raise ValueError(f'training.init_from: {path} has {cell} cells, this model '
                         f'{model.cell.name} cells')
    source = checkpoint.model_state
    own = model.state_dict()
    names = [n for n in own if n.startswith(WARM_START_LAYERS)]
    unfit = [n for n in names if n not in source or source[n].shape != own[n].shape]
    if unfit:
        raise ValueError(f'training.init_from: {path} is not a hybrid of this size '
                         f'({unfit[0]} missing or of another shape)')
    model.load_state_dict({n: source[n] for n in names}, strict=False)
    return {'path': str(path), 'layers': sorted({n.split('.')[0] for n in names}),
            'tensors': len(names)}


def _train(cfg: dict, spec: Vessel, ds: Dataset, out_dir: Path, resume: bool,
           group: Group) -> dict:
    tcfg = cfg['training']
    torch.set_num_threads(int(tcfg['threads']))
    torch.manual_seed(tcfg['seed'])
    if group.main:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / 'config.yaml').write_text(yaml.safe_dump(cfg, sort_keys=False))
    t_start = time.monotonic()
    cache = cache_dir(cfg, out_dir)
    try:
        return _train_cached(cfg, spec, ds, out_dir, resume, group, cache, t_start)
    finally:
        group.barrier()
        if group.local_rank == 0:
            shutil.rmtree(cache, ignore_errors=True)


def cache_dir(cfg: dict, out_dir: Path) -> Path:
    """Directory of the run cache: the config's, else one per output directory in /tmp."""
    given = cfg['training']['cache_dir']
    if given is not None:
        return Path(given)
    key = hashlib.sha256(str(out_dir.resolve()).encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / 'hybrid_models_cache' / key


def _train_cached(cfg, spec, ds, out_dir, resume, group, cache, t_start) -> dict:
    tcfg = cfg['training']
    # One process per machine writes the cache; the others stream the same statistics.
    writer = group.local_rank == 0
    if writer:
        cache.mkdir(parents=True, exist_ok=True)
    mirror = uses_mirror(tcfg['mirror'], spec)
    stores = {split: build_split(ds, split, spec, cache, tcfg['statistics_rows'],
                                 tcfg['seed'], writer, mirror and split == 'train')
              for split in ('train', 'val')}
    group.barrier()
    base = {'dataset': {'path': str(cfg['dataset']), 'sha256': dataset_hash(ds),
                        'train_runs': [r.run_id for r in stores['train'].runs],
                        'val_runs': [r.run_id for r in stores['val'].runs],
                        'mirrored': mirror},
            'vehicle': spec.to_dict(), 'training': cfg, 'name': cfg['name']}
    state_norm = stores['train'].state.normalizer()
    control_norm = stores['train'].control.normalizer()
    base['normalization'] = {'state': state_norm.to_dict(), 'control': control_norm.to_dict()}
    kind = cfg['model']['kind']
    if kind == 'qlag':
        # A closed-form baseline fitted in memory; every rank fits, rank 0 writes.
        train_runs = load_runs(ds, 'train', spec)
        val_runs = load_runs(ds, 'val', spec)
        model, extra = _fit_qlag(cfg, spec, train_runs, val_runs, state_norm)
        summary = {**base, **extra, 'model': model.describe()}
        if group.main:
            save_checkpoint(out_dir / MODEL_FILE, model, summary)
        return summary
    model = build_model(cfg['model'], spec)
    model.set_normalization(state_norm, control_norm)
    z_phy_train = z_phy_val = None
    if isinstance(model, HybridModel):
        z_phy_train, z_phy_val, phys_info = _prepare_physics(model, cfg, stores, cache,
                                                             writer)
        group.barrier()
        base.update(phys_info)
    if tcfg['init_from']:
        base['init_from'] = warm_start(model, Path(tcfg['init_from']))
    model.to(group.device)
    if isinstance(model, HybridModel) and tcfg['compiled_physics'] and \
            group.device.type == 'cpu':
        model.physical.compile()
    task = RecurrentTask(spec, stores['train'].runs, stores['val'].runs, tcfg, state_norm.std,
                         z_phy_train, z_phy_val, group=group)
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
    if isinstance(model, HybridModel) and tcfg['selection']['do_no_harm']:
        # Only this rank is left: it forecasts every validation window itself.
        base['selection'] = select_threshold(model, task.alone(), tcfg, state.best_epoch)
        base['bound'].update(relative_threshold=model.relative_threshold,
                             half_width=model.bound.tolist())
    if isinstance(model, HybridModel):
        base['bands'] = calibrate_bands(model, task.alone(), tcfg)
    summary = {**checkpoint_config(), 'val': best.config.get('val'),
               'best_epoch': state.best_epoch, 'epochs': state.epoch,
               'bad_steps': state.bad_steps, 'rollbacks': state.rollbacks,
               'stop_reason': state.stop_reason,
               'train_seconds': round(state.elapsed_s, 1),
               'wall_seconds_this_session': round(time.monotonic() - t_start, 1)}
    save_checkpoint(out_dir / MODEL_FILE, model, summary)
    return summary


def select_threshold(model: HybridModel, task: RecurrentTask, tcfg: dict,
                     best_epoch: int) -> dict:
    """
    Serve the best epoch at the threshold chosen on validation (``hybrid_models.selection``).

    The model keeps the chosen threshold or schedule (its config's ``relative_threshold``
    is the cap); the returned record holds the figures of every candidate and of the
    physics alone.
    """
    cap = model.relative_threshold
    grid = threshold_grid(tcfg['selection']['thresholds'], cap)
    std = task.state_std_np

    def figures(schedules: list) -> list[dict]:
        return [forecast_figures(pred, true, model.spec, std, runs)
                for pred, true, runs in task.validation_forecasts_at(model, schedules)]

    physics = figures([PHYSICS_ALONE])[0]
    if best_epoch == REFERENCE_EPOCH:
        choice = {'relative_threshold': PHYSICS_ALONE, 'score': physics['score'],
                  'reason': 'no epoch forecast the validation runs better than the physics '
                            'alone; the physics alone is served', 'candidates': []}
    else:
        choice = choose_schedule(figures, grid, physics, model.spec.dt,
                                 tcfg['selection']['confidence'])
    model.set_threshold(choice['relative_threshold'])
    print(f"served threshold {choice['relative_threshold']}: {choice['reason']}",
          file=sys.stderr)
    kept = {k: v for k, v in physics.items() if k != 'per_forecast'}
    return {**choice, 'cap': cap, 'grid': grid, 'physics': kept,
            'best_epoch': best_epoch}


def calibrate_bands(model: HybridModel, task: RecurrentTask, tcfg: dict) -> dict | None:
    """
    Return the served hybrid's forecast bands (``hybrid_models.bands``) as a config entry.

    From its forecasts of every validation run at the served threshold; None (said on
    stderr) when the config asks for none or the validation runs cannot give them.
    """
    levels, stride = tcfg['bands']['levels'], tcfg['bands']['stride']
    if not levels:
        return None
    pred, true, runs = task.validation_forecasts(model, stride)
    try:
        bands = calibrate(pred, true, model.spec, model.relative_threshold, levels, source={
            'split': 'val', 'runs': int(len(np.unique(runs))), 'stride': int(stride),
            'target': 'measured'})
    except BandsError as exc:
        print(f'no forecast bands: {exc}', file=sys.stderr)
        return None
    print(f'forecast bands from {len(pred)} validation forecasts', file=sys.stderr)
    return bands.to_dict()


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


def _prepare_physics(model: HybridModel, cfg, stores: dict, cache: Path, write: bool):
    """
    Fit the regression part, compute the output range, residual scale and bound.

    The fit uses the pairs sample (all one-step pairs up to ``statistics_rows``); one
    more streaming pass writes the one-step outputs ``z_phy`` of every run to the cache
    (teacher forcing reads them) and takes the residual statistics and the 95 % range.
    """
    physical = model.physical
    ns, nc = model.spec.n_state, model.spec.n_control
    pairs = stores['train'].pairs.rows()
    physical.fit(pairs[:, :ns], pairs[:, ns:ns + nc], pairs[:, ns + nc:])
    # The fitted values as the hybrid holds them (its buffers), taken once for every run.
    fitted = physical.numpy_model()
    residual, change = Moments(ns), Moments(ns)
    squares = np.zeros(ns)
    outputs = RowSample(cfg['training']['statistics_rows'], cfg['training']['seed'])
    z_phy = {}
    for split in ('train', 'val'):
        z_phy[split] = []
        for run in stores[split].runs:
            path = cache / f'{run.run_id}.phy.f32'
            writer = RowWriter(path if write else None)
            prev = None
            for block in run.chunks():
                rows = block if prev is None else np.concatenate([prev, block])
                one_step = fitted.predict(rows[:-1, :ns], rows[:-1, ns:ns + nc])
                writer.write(one_step)
                # The 95 % range is taken over training AND validation outputs (paper).
                outputs.add(one_step)
                if split == 'train':
                    error = rows[1:, :ns] - one_step
                    residual.add(error)
                    change.add(rows[1:, :ns] - rows[:-1, :ns])
                    squares += (np.asarray(error, np.float64) ** 2).sum(axis=0)
                prev = rows[-1:]
            writer.close()
            z_phy[split].append(RowFile(path, ns, run.length - 1))
    scale = residual if cfg['model']['residual_scale'] == 'physics_residual' else change
    model.residual_std.copy_(torch.as_tensor(scale.normalizer().std))
    r95 = output_range(outputs.rows())
    model.output_range.copy_(torch.as_tensor(r95))
    model.set_threshold(cfg['model']['relative_threshold'])
    one_step_rmse = np.sqrt(squares / residual.n)
    info = {'physics': _physics_info(fitted),
            'bound': {'definition': 'b_i = T * R_i / 2, R_i = q97.5 - q2.5 of one-step '
                                    'physical outputs on train+val',
                      'output_range': r95.tolist(),
                      'relative_threshold': cfg['model']['relative_threshold'],
                      'half_width': model.bound.tolist()},
            'physics_one_step_rmse': dict(zip(model.spec.state_names,
                                              one_step_rmse.tolist(), strict=True)),
            'residual_scale': {'from': cfg['model']['residual_scale'],
                               'std': model.residual_std.tolist()}}
    horizon = cfg['training']['validation']['horizon'] or model.spec.horizon
    info['physics_envelope'] = envelope_escapes(fitted, model.spec, pairs[:, :ns],
                                                pairs[:, ns:ns + nc], horizon)
    warning = escape_warning(info['physics_envelope'], _envelope_remedy(fitted))
    if warning:
        print(warning, file=sys.stderr)
    info['bound']['range_from'] = ('all one-step outputs' if outputs.complete else
                                   f'a uniform sample of {outputs.capacity} of '
                                   f'{outputs.seen} one-step outputs')
    model.novelty = calibrate_novelty(model, fitted, pairs, stores['val'].pairs.rows())
    return z_phy['train'], z_phy['val'], info


def calibrate_novelty(model: HybridModel, fitted, train_pairs: np.ndarray,
                      val_pairs: np.ndarray) -> novelty.Novelty:
    """Return where the correction is trained (``hybrid_models.novelty``), from the pairs."""
    ns, nc = model.spec.n_state, model.spec.n_control
    norm = {name: getattr(model, name).double().numpy()
            for name in ('state_mean', 'state_std', 'control_mean', 'control_std')}

    def inputs(rows: np.ndarray) -> np.ndarray:
        z, c = rows[:, :ns].astype(np.float64), rows[:, ns:ns + nc].astype(np.float64)
        return correction_input(norm, fitted.predict(z, c), c)

    return novelty.calibrate(inputs(train_pairs), inputs(val_pairs),
                             f'{len(train_pairs)} training and {len(val_pairs)} validation '
                             f'one-step inputs')


def _envelope_remedy(physical) -> str | None:
    """Return what a user can set against a physics that leaves the envelope, if anything."""
    if isinstance(physical, RegressionModel) and not physical.damped:
        return ("model.physical.damped: true keeps the regression's own gains <= 1 over the "
                "vessel's limits")
    return None


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
