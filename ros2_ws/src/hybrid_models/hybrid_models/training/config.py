"""
Training configurations: YAML files merged over documented defaults.

A config names the dataset, the model (kind, architecture, physical model,
constraint), the training phases and the evaluation protocol. Unknown keys are
errors, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import copy
from pathlib import Path

import yaml

import hybrid_models
from hybrid_models.data import evaluation_protocol
from hybrid_models.recurrent import cell_of
from vessel_description.resources import data_dir, read_yaml

DEFAULTS: dict = {
    'name': 'unnamed',
    'dataset': None,            # dataset directory (vessel_datasets format); its
                                # vessel description gives vectors, rate and the
                                # window/horizon defaults below
    'vessel': None,             # optional vessel file the dataset must match (refused
                                # with one line when its vectors or rate differ)
    'model': {
        'kind': 'hybrid',       # qlag | lstm | hybrid
        'cell': 'lstm',         # the recurrent cell of lstm and hybrid: lstm (the paper's)
                                # or gru (hybrid_models.recurrent; docs/extending.md)
        'hidden': 64,
        'layers': 2,
        'dropout': 0.25,
        'physical': {'kind': 'lin'},
        'bound_mode': 'tanh',   # tanh | clamp (hybrid.bound)
        'bound_in_training': False,
        'correction_init': 'zero',   # zero: training starts from the physics' forecast;
                                     # random: torch's default initialization of the head
        # What scales the correction's output (hybrid_step: residual_std): the spread of
        # the physics' one-step residual on the training runs (physics_residual, the
        # paper's normalisation), or that of the measured states' one-step change
        # (state_change: a property of the data alone, so a better physics does not
        # shrink the correction's steps and slow its learning).
        'residual_scale': 'physics_residual',
        'relative_threshold': None,   # the largest threshold served, e.g. 0.15 (None: no
                                      # cap); the served one is chosen on validation
                                      # (training.selection)
        # Serve the bound faded where the correction's inputs leave what training and
        # validation covered (hybrid_models.novelty; every hybrid is calibrated, this
        # turns the fade on; set_novelty turns it on or off afterwards).
        'novelty_fade': False,
        'lags': [1, 2, 4, 8],   # QLag: candidate lags, chosen on validation
        'lag': 4,
        'ridge': 1.0e-8,
    },
    'training': {
        'seed': 0,
        # More than 1: an ensemble of that many hybrids (seeds seed, seed + 1, ...) served
        # as one (hybrid_models.ensemble): the mean of their corrections at every step.
        'members': 1,
        'threads': 2,
        'window': None,         # initialization window (samples); None: the vessel's
        'sequence_length': 50,  # predicted samples per training sequence (BPTT length)
        'batch_size': 256,
        # Few recordings give few sequences: the batch shrinks (not below the minimum)
        # so that an epoch still takes this many optimizer steps.
        'min_batches_per_epoch': 16,
        'min_batch_size': 8,
        'grad_clip': 1.0,       # max global gradient norm
        'weight_decay': 0.0,
        'phases': [
            # teacher: phase 1 of 2P (one-step residual, true states in);
            # multistep: feedback of predictions (1P uses only this phase).
            {'kind': 'teacher', 'max_epochs': 20, 'patience': 4, 'lr': 0.0025,
             'stop_loss': None},
            {'kind': 'multistep', 'max_epochs': 60, 'patience': 8, 'lr': 0.0025},
        ],
        'validation': {'horizon': None, 'stride': None},  # samples; None: the vessel's
                                                           # horizon, stride horizon/3
        'max_bad_step_fraction': 0.5,  # more skipped (non-finite) steps: roll the epoch back
        'time_limit_minutes': None,    # stop (keeping the best model) past this budget
        'cache_dir': None,      # float32 copies of the runs that windows are read from;
                                # None: <tmp>/hybrid_models_cache/<hash of the out dir>,
                                # removed when training ends
        'statistics_rows': 1_000_000,  # one-step pairs (and physics outputs) kept for
                                       # the physics fit and the 95 % range: all of
                                       # them up to this many, else a uniform sample
        'progress': True,
        # Port/starboard mirror images of the training runs as more training runs:
        # auto when the vessel file declares its mirror image (key mirror: a vessel
        # symmetric about its centre plane, actuators included), true, or false.
        'mirror': 'auto',
        # A hybrid's physical part as one compiled program (JAX) with its Jacobian for
        # the backward pass (hybrid_models.compiled_physics), on CPUs: the same step,
        # several times faster for first-principles physics; false: torch's autograd.
        'compiled_physics': True,
        # A hybrid checkpoint of the same size whose recurrent layers (init and lstm)
        # start this training, e.g. the hybrid on the nominal physics for the one on the
        # augmented physics; the correction's head still starts as model.correction_init,
        # so the training still starts from its own physics' forecast. null: none.
        'init_from': None,
        # Do no harm (hybrid_models.selection): after training, the served relative
        # threshold is chosen on the validation runs among these (0, the physics alone,
        # always included; none above model.relative_threshold when that is set; null:
        # unbounded) as the best one not worse than the physics alone at any reported
        # step. false: serve model.relative_threshold as configured.
        # "Worse" is judged per forecast, paired with the physics alone: worse beyond
        # the validation runs' sampling error at this one-sided confidence (null: any
        # difference at all counts).
        'selection': {'do_no_harm': True,
                      'thresholds': [0.0, 0.01, 0.025, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0],
                      'confidence': 0.95},
        # Calibrated forecast bands (hybrid_models.bands) of the served hybrid, from its
        # forecasts of the validation runs (one every `stride` samples; null: the
        # validation horizon / 30), stored in the checkpoint; levels [] computes none.
        'bands': {'levels': [0.5, 0.9], 'stride': None},
    },
    # None: the vessel's horizon; stride horizon/7.5 (120 s of the paper's 900 s)
    'evaluation': {'horizon': None, 'stride': None, 'target': 'true',
                   'thresholds': [0.025, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5]},
}

PHASE_KEYS = {'kind', 'max_epochs', 'patience', 'lr', 'stop_loss', 'sequence_length'}
PHASE_KINDS = ('teacher', 'multistep')
RESIDUAL_SCALES = ('physics_residual', 'state_change')


class ConfigError(ValueError):
    """A configuration is malformed."""


def _merge(base: dict, override: dict, where: str) -> dict:
    out = copy.deepcopy(base)
    for key, value in override.items():
        if key not in base:
            raise ConfigError(f'unknown config key {where}{key!r}; known: {sorted(base)}')
        if isinstance(base[key], dict) and key != 'physical':
            if not isinstance(value, dict):
                raise ConfigError(f'config key {where}{key!r} must be a mapping')
            out[key] = _merge(base[key], value, f'{where}{key}.')
        else:
            out[key] = copy.deepcopy(value)
    return out


def resolve(cfg: dict) -> dict:
    """Merge a partial config over the defaults and check it."""
    out = _merge(DEFAULTS, cfg or {}, '')
    for i, phase in enumerate(out['training']['phases']):
        extra = set(phase) - PHASE_KEYS
        if extra or phase.get('kind') not in PHASE_KINDS:
            raise ConfigError(f'training.phases[{i}]: kind must be one of {PHASE_KINDS} '
                              f'and keys among {sorted(PHASE_KEYS)} (got {phase})')
    if out['model']['residual_scale'] not in RESIDUAL_SCALES:
        raise ConfigError(f"model.residual_scale must be one of {RESIDUAL_SCALES}, got "
                          f"{out['model']['residual_scale']!r}")
    try:
        cell_of(out['model']['cell'])
    except ValueError as exc:
        raise ConfigError(f'model.cell: {exc}') from None
    members = out['training']['members']
    if isinstance(members, bool) or not isinstance(members, int) or members < 1:
        raise ConfigError(f'training.members must be a whole number >= 1, got {members!r}')
    kind = out['model']['kind']
    if kind == 'lstm' and any(p['kind'] == 'teacher' for p in out['training']['phases']):
        raise ConfigError('the LSTM baseline has no physical model to teacher-force; '
                          'give it only multistep phases')
    return out


def fill_from_vessel(cfg: dict, vessel) -> dict:
    """
    Window, horizons and strides the config leaves open, from the vessel's description.

    Validation forecasts start every horizon/3 samples (300 for 900 s at 1 Hz), test
    forecasts as ``evaluation_protocol`` says.
    """
    out = copy.deepcopy(cfg)
    t, v, e = out['training'], out['training']['validation'], out['evaluation']
    t['window'], e['horizon'], e['stride'] = evaluation_protocol(
        vessel, t['window'], e['horizon'], e['stride'])
    _, v['horizon'], _ = evaluation_protocol(vessel, t['window'], v['horizon'], 1)
    v['stride'] = int(v['stride'] if v['stride'] is not None else max(1, v['horizon'] // 3))
    b = t['bands']
    b['stride'] = int(b['stride'] if b['stride'] is not None else max(1, v['horizon'] // 30))
    return out


def config_dir() -> Path:
    """Return the package's config/ folder: the source tree's, else the installed share's."""
    return data_dir('hybrid_models', hybrid_models.__file__, 'config')


def load_config(path: str | Path, overrides: list[str] | None = None) -> dict:
    """Read a YAML config, apply dotted overrides ('dataset=DIR', 'model.hidden=128')."""
    path = Path(path)
    raw = read_yaml(path, ConfigError, 'config') or {}
    if not isinstance(raw, dict):
        raise ConfigError(f'{path}: a config must be a mapping')
    raw.setdefault('name', path.stem)
    return resolve(apply_overrides(raw, overrides or []))


def parse_override(text: str) -> tuple[list[str], object]:
    """
    'model.physical.kind=min+lin' -> (['model', 'physical', 'kind'], 'min+lin').

    The value is read as YAML, so numbers, null and lists work: 'a.b=0.15', 'a=[1, 2]'.
    """
    if '=' not in text:
        raise ConfigError(f'override {text!r} must look like key.sub=value')
    key, value = text.split('=', 1)
    return key.strip().split('.'), yaml.safe_load(value)


def apply_overrides(raw: dict, overrides: list[str]) -> dict:
    """Set dotted keys in a raw (unresolved) config, creating mappings as needed."""
    raw = copy.deepcopy(raw)
    for text in overrides:
        path, value = parse_override(text)
        node = raw
        for part in path[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f'override {text!r}: {part!r} is not a mapping')
        node[path[-1]] = value
    return raw
