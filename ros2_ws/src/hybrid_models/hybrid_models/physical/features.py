"""
Named feature maps for the regression components, with per-state masks.

Every feature has a name; a regression row (one output state) uses the features its
mask names. Masks are defined by NAME, never by column position, so prepending
controls or adding features cannot shift them (a defect of the authors' library).

- ``lin``: controls and states (Baier et al. eq. "Lin": z' = Q c + P z + b).
- ``qua``: ``lin`` plus the square of every control and state (the quadcopter "Qua").
- ``hyd``: ``lin`` plus the nonlinear hull terms of Blanke & Christensen (1993) as
  used for the patrol vessel by Perez, Ross & Fossen (2006): the patrol family's
  ``features`` (``Family.features``, its ``feature`` terms in order), each with the
  generalized forces it enters, for any vessel with the ship's states.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vessel_description import Vessel
from vessel_physics.arrays import namespace
from vessel_physics.families import FAMILIES

Term = Callable[[dict], object]   # state values by name -> one feature (an array)

# The hull features in the order of the regression's columns (a checkpoint's weights
# follow it), and which generalized forces each enters: the family's own.
_HULL = FAMILIES['patrol']
BLANKE_TERMS: dict[str, Term] = {name: _HULL.terms[name].fn for name in _HULL.features}
DOF_TERMS: dict[str, tuple[str, ...]] = {
    dof: tuple(n for n in _HULL.features if dof in _HULL.terms[n].dofs) for dof in 'XYKN'}

# Forces acting on each state over one sample period. 'diagonal' reads Blanke's
# equations literally (one force per acceleration, phi' = p has none). 'coupled'
# respects the mass matrix: its sway/roll/yaw block is full, so v', p', r' each see
# Y, K and N; and phi integrates p over the 1 s period, so it sees them too.
MASK_MODES: dict[str, dict[str, tuple[str, ...]]] = {
    'diagonal': {'u': ('X',), 'v': ('Y',), 'p': ('K',), 'r': ('N',), 'phi': ()},
    'coupled': {'u': ('X',), 'v': ('Y', 'K', 'N'), 'p': ('Y', 'K', 'N'),
                'r': ('Y', 'K', 'N'), 'phi': ('Y', 'K', 'N')},
}


def term_states(term: Term) -> frozenset[str]:
    """Return the states a hull term reads (found by evaluating it on a recorder)."""
    seen: set[str] = set()

    class Recorder(dict):
        def __missing__(self, key):
            seen.add(key)
            return 1.0

    term(Recorder())
    return frozenset(seen)


class FeatureMap:
    """Maps (z, c) to named features (B, F); ``masks[state]`` lists the features it uses."""

    def __init__(self, spec: Vessel, kind: str = 'lin', masks: str = 'coupled'):
        if kind not in ('lin', 'qua', 'hyd'):
            raise ValueError(f"unknown feature map {kind!r}; use 'lin', 'qua' or 'hyd'")
        self.spec, self.kind, self.mask_mode = spec, kind, masks
        linear = list(spec.control_names) + list(spec.state_names)
        self.names: tuple[str, ...]
        if kind == 'lin':
            self.names = tuple(linear)
        elif kind == 'qua':
            self.names = tuple(linear + [f'{n}^2' for n in linear])
        else:
            missing = {'u', 'v', 'r'} - set(spec.state_names)
            if missing:
                raise ValueError(f'Blanke features need ship states; {spec.name} lacks '
                                 f'{sorted(missing)}')
            if masks not in MASK_MODES:
                raise ValueError(f'unknown mask mode {masks!r}; use {sorted(MASK_MODES)}')
            # A 3-DOF vessel keeps the hull terms of its own states (no roll terms).
            have = set(spec.state_names)
            self.terms = [t for t, f in BLANKE_TERMS.items() if term_states(f) <= have]
            self.names = tuple(linear + self.terms)
        self.masks = {s: self._mask_names(s, linear) for s in spec.state_names}

    def _mask_names(self, state: str, linear: list[str]) -> tuple[str, ...]:
        if self.kind != 'hyd':
            return self.names
        terms = {t for dof in MASK_MODES[self.mask_mode][state] for t in DOF_TERMS[dof]}
        # Keep the canonical order of BLANKE_TERMS; every row keeps all linear terms.
        return tuple(linear + [t for t in self.terms if t in terms])

    def mask_matrix(self) -> np.ndarray:
        """Boolean (n_state, F): row i marks the features of state i."""
        rows = [[n in set(self.masks[s]) for n in self.names] for s in self.spec.state_names]
        return np.array(rows, dtype=bool)

    def array_features(self, z, c):
        """Features (..., F) in the order of ``names``, on any Array API arrays."""
        xp = namespace(z, c)
        linear = xp.concat([c, z], axis=-1)
        if self.kind == 'lin':
            return linear
        if self.kind == 'qua':
            return xp.concat([linear, linear * linear], axis=-1)
        s = {name: z[..., i] for i, name in enumerate(self.spec.state_names)}
        blanke = xp.stack([BLANKE_TERMS[t](s) for t in self.terms], axis=-1)
        return xp.concat([linear, blanke], axis=-1)
