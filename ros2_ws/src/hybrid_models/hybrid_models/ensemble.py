"""
Several trained corrections on one physics, served as one hybrid.

A correction learnt from a few runs depends on its seed as much as on the data: five
seeds of the same config gave trajectory errors 31-56 m where the physics alone gave 48
m (issue #23, a KVLCC2 campaign at full scale). An ensemble of K hybrids of one config,
trained with K seeds on the same data, forecasts with the mean of their corrections at
every step (``hybrid_step.ensemble_step``): one trajectory, the physics plus the
members' mean bounded residual, so the interpretability bound holds as for one hybrid.
The members keep their own LSTM, head and normalization; the physics is the first
member's (``pack`` refuses members whose physics differ), and one relative threshold
serves them all.

``pack(members)`` builds an ``EnsembleHybrid`` from trained ``HybridModel``s;
``is_hybrid`` tells whether a model is served at a threshold (one hybrid or an ensemble).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from hybrid_models.bound import ServedThreshold
from hybrid_models.hybrid_step import ENSEMBLE_KIND, ensemble_step
from hybrid_models.nets import HybridModel, roll_out
from hybrid_models.physical.identity import physics_identity

KIND = ENSEMBLE_KIND


class EnsembleError(ValueError):
    """Members that cannot be served together; the message is one line."""


class EnsembleHybrid(nn.Module, ServedThreshold):
    """K hybrids of one config on one physics; each step adds their mean correction."""

    kind = KIND

    def __init__(self, members: Sequence[HybridModel]):
        super().__init__()
        if len(members) < 2:
            raise EnsembleError(f'an ensemble needs at least 2 members, got {len(members)}')
        self.members = nn.ModuleList(members)
        self.spec = members[0].spec

    # ------------------------------------------------- what a single hybrid offers too
    @property
    def physical(self):
        """Return the physics every member corrects (the first member's module)."""
        return self.members[0].physical

    @property
    def relative_threshold(self):
        """Return the threshold (or schedule) every member is served at."""
        return self.members[0].relative_threshold

    @relative_threshold.setter
    def relative_threshold(self, value) -> None:
        for member in self.members:
            member.relative_threshold = value

    @property
    def bound(self) -> torch.Tensor:
        """Return the served half-widths (equal for all members: one physics)."""
        return self.members[0].bound

    @property
    def output_range(self) -> torch.Tensor:
        """Return the physics' 95 % one-step output range the threshold is relative to."""
        return self.members[0].output_range

    def set_threshold(self, relative_threshold) -> None:
        """Serve every member at ``relative_threshold`` (``HybridModel.set_threshold``)."""
        for member in self.members:
            member.set_threshold(relative_threshold)

    def step_bounds(self, horizon: int) -> torch.Tensor | None:
        """Half-widths (horizon, n_state) of the served threshold; None when constant."""
        return self.members[0].step_bounds(horizon)

    def bounds_at(self, relative_threshold, horizon: int) -> torch.Tensor:
        """Half-widths (horizon, n_state) of any threshold or schedule (inf: unbounded)."""
        return self.members[0].bounds_at(relative_threshold, horizon)

    def forecast(self, z_window: torch.Tensor, c_window: torch.Tensor,
                 c_future: torch.Tensor, return_parts: bool = False,
                 bounds: torch.Tensor | None = None):
        """Multistep prediction with feedback, as ``HybridModel.forecast`` (``bounds`` too)."""
        recurrents = tuple(m.start(z_window, c_window) for m in self.members)
        weights = tuple(m.step_weights() for m in self.members)
        if bounds is None:
            bounds = self.step_bounds(c_future.shape[1])
        cell, mode = self.members[0].cell, self.members[0]._bound_mode()
        return roll_out(lambda z, c, recurrents, bound: ensemble_step(
            cell, weights, self.physical, z, c, recurrents, mode, bound),
            z_window[:, -1], c_future, recurrents, bounds, return_parts)

    def describe(self) -> dict:
        """Architecture (``build_model`` input): the member's description and the count."""
        return {'kind': KIND, 'members': len(self.members),
                'member': self.members[0].describe(),
                'relative_threshold': self.relative_threshold}


def architecture(model: HybridModel) -> dict:
    """
    Return what members must share to be served as one: the model's construction.

    Without the served threshold (the ensemble chooses its own) and without the physical
    part: ``physics_identity`` compares that whole, by its description and learned
    values, not by the paths its files were read from (one physics copied to another
    folder is the same physics, of any physical kind).
    """
    return {k: v for k, v in model.describe().items()
            if k not in ('relative_threshold', 'physical')}


def pack(members: Sequence[HybridModel]) -> EnsembleHybrid:
    """
    Return the ensemble of trained hybrids, checked to be servable together.

    Refused in one line: fewer than two, a model that is not a hybrid, members of
    another vessel or rate, another architecture, or another physics (its fingerprint:
    description and every learned value).
    """
    members = list(members)
    for i, m in enumerate(members):
        if not isinstance(m, HybridModel):
            raise EnsembleError(f'member {i} is a {type(m).__name__}, not a hybrid: only '
                                f'hybrids on one physics form an ensemble')
    if len(members) < 2:
        raise EnsembleError(f'an ensemble needs at least 2 members, got {len(members)}')
    first = members[0]
    physics, shape = physics_identity(first.physical), architecture(first)
    for i, m in enumerate(members[1:], start=1):
        m.spec.check_compatible(first.spec, f'member 0 of the ensemble (member {i})')
        if architecture(m) != shape:
            raise EnsembleError(f'member {i} has another architecture than member 0: '
                                f'{architecture(m)} against {shape}')
        own = physics_identity(m.physical)
        if own != physics:
            raise EnsembleError(f'member {i} corrects another physics ({own[1]}) than '
                                f'member 0 ({physics[1]}): an ensemble shares one physics')
    ensemble = EnsembleHybrid(members)
    ensemble.set_threshold(first.relative_threshold)
    return ensemble


def is_hybrid(model: nn.Module) -> bool:
    """Tell whether a model is a hybrid served at a threshold (one, or an ensemble)."""
    return isinstance(model, (HybridModel, EnsembleHybrid))
