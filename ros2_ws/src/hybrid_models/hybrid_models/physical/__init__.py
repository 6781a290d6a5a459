"""
Physical models: first principles (any family's physics), regression (Lin, Hyd, Qua), sums.

``build_physical({'kind': 'pro+lin', ...}, vessel)`` makes any of them; kinds are written
like the paper's names in lower case: 'min', 'pro', 'lin', 'hyd', 'qua', 'min+lin', ...
Kind 'physics' is the first-principles model of a physics file (``physics: PATH``) of any
family (``vessel_physics``): the patrol boat's, an MMG ship's, a Fossen small craft's, a
multirotor's, or the augmented physics the diagnosis writes; 'physics+lin' etc. combine
it too. Each family's name is a kind of its own -- 'patrol', 'mmg', 'fossen',
'multirotor': the family's model (optionally some of its force ``terms``) -- and so are
its named term sets -- 'min' and 'pro' of the patrol family (the paper's), 'minq' of the
multirotor family (the paper's quadrotor) --, each on the physics the vessel file names.
"""

from __future__ import annotations

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.physical.composite import CompositeModel
from hybrid_models.physical.first_principles import PHYSICS_FILE_KIND, build_first_principles
from hybrid_models.physical.regression import RegressionModel
from vessel_description import Vessel
from vessel_physics.families import FAMILIES

REGRESSION_KINDS = ('lin', 'hyd', 'qua')

__all__ = ['PhysicalModel', 'CompositeModel', 'RegressionModel', 'build_physical',
           'REGRESSION_KINDS', 'first_principles_kinds']


def first_principles_kinds() -> tuple[str, ...]:
    """Return the first-principles kinds: 'physics', the families' names, their term sets."""
    sets = sorted({name for family in FAMILIES.values() for name in family.term_sets})
    return (PHYSICS_FILE_KIND, *FAMILIES, *sets)


def build_physical(cfg: dict, spec: Vessel) -> PhysicalModel:
    """
    Construct (unfitted) the physical model a config names.

    Keys: ``kind``; for regressions ``ridge`` (relative, default 1e-8), ``masks``
    ('coupled' or 'diagonal', Hyd only) and ``damped`` (a regression alone: each state's
    own one-step gain kept <= 1 over the vessel's envelope; default false, the paper's
    fit); for first principles ``physics`` (kind
    'physics': a physics file's path; any kind: the mapping a checkpoint stores, with
    ``physics_source`` where it came from), ``params`` (a physics or parameter file,
    default the one the vessel file names), ``terms`` (a family's kind: force terms),
    ``substeps`` (RK4 sub-steps per sample period) and, from older checkpoints, the
    parameter values ``vessel`` / ``mmg``.
    """
    kind = str(cfg.get('kind', '')).lower()
    parts = kind.split('+')
    first = first_principles_kinds()
    fp_kind = parts[0] if parts[0] in first else None
    reg_kinds = parts[1:] if fp_kind else parts
    if len(reg_kinds) > 1 or (reg_kinds and reg_kinds[0] not in REGRESSION_KINDS) or (
            not fp_kind and not reg_kinds):
        raise ValueError(f'unknown physical model {kind!r}; use one of '
                         f'{first + REGRESSION_KINDS} or first+regression, '
                         f"e.g. 'min+lin'")
    damped = cfg.get('damped', False)
    if not isinstance(damped, bool):
        raise ValueError(f'physical.damped: true or false, got {damped!r}')
    if damped and (fp_kind or not reg_kinds):
        raise ValueError(f'physical.damped: bounds the gain of a regression that forecasts '
                         f'the next state alone (lin, hyd, qua), not of {kind!r}')
    regression = None
    if reg_kinds:
        regression = RegressionModel(spec, reg_kinds[0], ridge=cfg.get('ridge', 1e-8),
                                     masks=cfg.get('masks', 'coupled'), damped=damped)
    if fp_kind is None:
        return regression
    fp = build_first_principles(fp_kind, spec, cfg, int(cfg.get('substeps', 4)))
    return fp if regression is None else CompositeModel(fp, regression)
