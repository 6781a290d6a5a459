"""
Settings of the diagnosis: the packaged defaults, a family's, and overrides.

``load_settings(path, family=NAME)`` merges, in this order, config/diagnosis.yaml (the
defaults, written for the patrol boat's size and time scales), the family's
config/families/NAME.yaml (time scales and force floors of the family's shipped vessels:
the MMG model tanker, the Otter), a user's YAML and ``overrides``; an unknown section or
key raises ``SettingsError`` with one line (and a did-you-mean), a wrong type too. A
setting that is null takes the vessel's own value (the evaluation's window and horizon).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from vessel_description.resources import data_dir, read_yaml
from vessel_physics.errors import did_you_mean


class SettingsError(ValueError):
    """A settings file is invalid; the message is one line."""


@dataclass(frozen=True)
class Prediction:
    """Numerical prediction of the physics."""

    substeps: int


@dataclass(frozen=True)
class Residuals:
    """Residuals and their filtering before the regression."""

    multistep_horizon_s: float
    lowpass_period_s: float
    lowpass_order: int


@dataclass(frozen=True)
class Regression:
    """Free-run segments whose residuals the candidates are regressed on."""

    horizon_s: float
    skip_s: float
    substeps: int


@dataclass(frozen=True)
class Locate:
    """Residual maps against regimes and time windows."""

    bins: int
    min_bin_samples: int
    window_s: float
    window_flag: float
    force_floor: tuple[float, float, float, float]
    sea_state_window_s: float


@dataclass(frozen=True)
class Selection:
    """Sparse regression with block-bootstrap inclusion probabilities."""

    bootstrap: int
    block_s: float
    seed: int
    inclusion_threshold: float
    max_terms: int
    rounds: int
    gauss_newton_iterations: int
    final_gauss_newton_iterations: int


@dataclass(frozen=True)
class Validation:
    """Held-out check that a selected term improves predictions."""

    folds: int
    min_improvement: float
    max_parameter_change: float
    kept_out_share: float


@dataclass(frozen=True)
class Collinearity:
    """When two candidates cannot be told apart."""

    alias_share: float
    alias_min_correlation: float


@dataclass(frozen=True)
class Excitation:
    """Whether the recordings can identify anything."""

    min_duration_s: float
    identifiable_se: float
    min_categories: int


@dataclass(frozen=True)
class ScaleCheck:
    """Whether the recordings move like a vessel of the vessel file's length (scale.py)."""

    quantile: float
    max_froude: float
    turning_speed_share: float
    max_turning_rate: float
    limits_margin: float


@dataclass(frozen=True)
class Evaluation:
    """Before/after errors on held-out recordings, and when the augmented physics is kept."""

    holdout_fraction: float
    holdout_seed: int
    calibration_s: float
    window_s: float | None
    horizon_s: float | None
    stride_s: float
    min_trajectory_gain: float
    max_state_loss: float


@dataclass(frozen=True)
class Settings:
    """Every setting of the diagnosis (see config/diagnosis.yaml)."""

    prediction: Prediction
    residuals: Residuals
    regression: Regression
    locate: Locate
    selection: Selection
    validation: Validation
    collinearity: Collinearity
    excitation: Excitation
    evaluation: Evaluation
    scale_check: ScaleCheck

    def to_dict(self) -> dict:
        """Return the settings as a plain mapping."""
        return asdict(self)

    def samples(self, seconds: float, dt: float) -> int:
        """Return a span of seconds in samples of period ``dt`` (at least one)."""
        return max(1, int(round(seconds / dt)))


def config_dir() -> Path:
    """Directory of the packaged YAML files (source tree or colcon install)."""
    return data_dir('vessel_diagnosis', __file__, 'config')


def _read(path: Path) -> dict:
    data = read_yaml(path, SettingsError, 'settings') or {}
    if not isinstance(data, Mapping):
        raise SettingsError(f'{path}: expected a mapping of sections')
    return dict(data)


def _section(cls, values: Mapping, defaults: Mapping, where: str):
    names = [f.name for f in fields(cls)]
    for key in values:
        if key not in names:
            raise SettingsError(f'{where}.{key}: unknown key{did_you_mean(str(key), names)}; '
                                f'allowed: {", ".join(names)}')
    out = {}
    for f in fields(cls):
        value = values.get(f.name, defaults[f.name])
        kind = str(f.type)
        if value is None and 'None' in kind:
            out[f.name] = None
        elif kind.startswith('tuple'):
            if not isinstance(value, list) or not value or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                raise SettingsError(f'{where}.{f.name}: expected a list of numbers, got '
                                    f'{value!r}')
            out[f.name] = tuple(float(v) for v in value)
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SettingsError(f'{where}.{f.name}: expected a number, got {value!r}')
        elif kind == 'int':
            if float(value) != int(value):
                raise SettingsError(f'{where}.{f.name}: expected an integer, got {value!r}')
            out[f.name] = int(value)
        else:
            out[f.name] = float(value)
    return cls(**out)


def family_settings_path(family: str) -> Path:
    """Path of a family's packaged settings (config/families/NAME.yaml)."""
    return config_dir() / 'families' / f'{family}.yaml'


def load_settings(path: str | Path | None = None, overrides: Mapping | None = None,
                  family: str | None = None) -> Settings:
    """Return the defaults, the family's, the YAML file ``path`` and ``overrides``, merged."""
    defaults = _read(config_dir() / 'diagnosis.yaml')
    user: dict = {}
    layers = []
    if family is not None and family_settings_path(family).is_file():
        layers.append(_read(family_settings_path(family)))
    layers += [_read(Path(path)) if path else {}, dict(overrides or {})]
    for layer in layers:
        for key, value in layer.items():
            if key not in defaults:
                user[key] = value    # refused below with a did-you-mean
                continue
            if not isinstance(value, Mapping):
                raise SettingsError(f'{path or "settings"}: {key}: expected a mapping')
            user[key] = {**user.get(key, {}), **value}
    sections = {f.name: f.type for f in fields(Settings)}
    for key in user:
        if key not in sections:
            raise SettingsError(f'{path or "settings"}: {key}: unknown section'
                                f'{did_you_mean(str(key), sections)}; allowed: '
                                f'{", ".join(sections)}')
    classes = {'prediction': Prediction, 'residuals': Residuals, 'regression': Regression,
               'locate': Locate,
               'selection': Selection, 'validation': Validation,
               'collinearity': Collinearity, 'excitation': Excitation,
               'evaluation': Evaluation, 'scale_check': ScaleCheck}
    built = {}
    for name, cls in classes.items():
        values = user.get(name, {})
        if not isinstance(values, Mapping):
            raise SettingsError(f'{path or "settings"}: {name}: expected a mapping')
        built[name] = _section(cls, values, defaults[name], name)
    return Settings(**built)
