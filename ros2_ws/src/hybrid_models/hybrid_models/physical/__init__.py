"""
Physical models: first principles (Min, Pro, MMG), regression (Lin, Hyd, Qua), combinations.

``build_physical({'kind': 'pro+lin', ...}, spec)`` makes any of them; kinds are written
like the paper's names in lower case: 'min', 'pro', 'lin', 'hyd', 'qua', 'min+lin', ...
Kind 'physics' is the first-principles model of a physics file (``physics: PATH``) of any
family, such as the augmented physics the diagnosis writes; 'physics+lin' etc. combine
it too. Kind 'mmg' is the MMG standard model of a 3-DOF single-screw, single-rudder ship
(``hybrid_models.physical.mmg_model``), which an MMG parameter file given to 'physics'
builds as well.
"""

from __future__ import annotations

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.physical.composite import CompositeModel
from hybrid_models.physical.regression import RegressionModel
from hybrid_models.vehicle import VehicleSpec

REGRESSION_KINDS = ('lin', 'hyd', 'qua')
FIRST_PRINCIPLES_KINDS = ('min', 'pro', 'physics', 'mmg')

__all__ = ['PhysicalModel', 'CompositeModel', 'RegressionModel', 'build_physical',
           'REGRESSION_KINDS', 'FIRST_PRINCIPLES_KINDS']


def build_physical(cfg: dict, spec: VehicleSpec) -> PhysicalModel:
    """
    Construct (unfitted) the physical model a config names.

    Keys: ``kind``; for regressions ``ridge`` (relative, default 1e-8) and ``masks``
    ('coupled' or 'diagonal', Hyd only); for first principles ``params`` (YAML path,
    default the file the vessel description names), ``vessel`` / ``mmg`` (parameter
    values, as stored in checkpoints; they win over ``params``), ``physics`` (kind
    'physics': a physics file's path or mapping; ``physics_source`` where a stored mapping
    came from), ``terms`` (kind 'mmg': force groups) and ``substeps`` (RK4 sub-steps per
    sample period).
    """
    kind = str(cfg.get('kind', '')).lower()
    parts = kind.split('+')
    fp_kind = parts[0] if parts[0] in FIRST_PRINCIPLES_KINDS else None
    reg_kinds = parts[1:] if fp_kind else parts
    if len(reg_kinds) > 1 or (reg_kinds and reg_kinds[0] not in REGRESSION_KINDS) or (
            not fp_kind and not reg_kinds):
        raise ValueError(f'unknown physical model {kind!r}; use one of '
                         f'{FIRST_PRINCIPLES_KINDS + REGRESSION_KINDS} or first+regression, '
                         f"e.g. 'min+lin'")
    regression = None
    if reg_kinds:
        regression = RegressionModel(spec, reg_kinds[0], ridge=cfg.get('ridge', 1e-8),
                                     masks=cfg.get('masks', 'coupled'))
    if fp_kind is None:
        return regression
    # Imported here so that regression-only models work without the vessel physics.
    if fp_kind == 'physics' and _is_mmg_file(cfg.get('physics')):
        # Kind 'physics' takes any physics file: an MMG parameter file is the MMG model.
        fp_kind, cfg = 'mmg', {**cfg, 'params': cfg['physics']}
    if fp_kind == 'mmg':
        from hybrid_models.physical.mmg_model import build_mmg
        fp = build_mmg(spec, params=cfg.get('params'), values=cfg.get('mmg'),
                       substeps=int(cfg.get('substeps', 4)), terms=cfg.get('terms'))
        return fp if regression is None else CompositeModel(fp, regression)
    from hybrid_models.physical.first_principles import build_first_principles
    fp = build_first_principles(fp_kind, spec, params=cfg.get('params'),
                                substeps=int(cfg.get('substeps', 4)), vessel=cfg.get('vessel'),
                                physics=cfg.get('physics'),
                                physics_source=cfg.get('physics_source'))
    return fp if regression is None else CompositeModel(fp, regression)


def _is_mmg_file(physics) -> bool:
    """Tell whether ``physics`` names an MMG parameter file (path or packaged name)."""
    if not isinstance(physics, str):
        return False
    from vessel_physics import mmg
    from vessel_physics.errors import ConfigError
    try:
        return mmg.is_mmg_file(mmg.find_params_file(physics))
    except ConfigError:
        return False
