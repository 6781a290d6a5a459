"""
The MMG standard model (``vessel_physics.mmg``) as a physical model of the hybrid.

For any 3-DOF vessel (states u, v, r) with one propeller and one rudder: the vessel
file's ``physics:`` names an MMG parameter file (``format: mmg-params/1``), or the
model config gives one (``params``) or the values themselves (``mmg``, as checkpoints
store them). ``terms`` picks force groups of ``vessel_physics.mmg.TERMS`` (default all:
inertial, hull, propeller, rudder), the MMG analogue of the paper's Min/Pro subsets.
The sway state is taken as the sway velocity at midship, the MMG reference point.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict

from hybrid_models.physical.integrated import IntegratedModel
from hybrid_models.vehicle import VehicleSpec
from vessel_physics import mmg
from vessel_physics.arrays import namespace
from vessel_physics.errors import ConfigError

KIND = 'mmg'


def _control_columns(spec: VehicleSpec) -> tuple[int, int]:
    """Return the columns of c holding the propeller (rad/s) and the rudder (rad)."""
    kinds = [a.kind for a in spec.actuators]
    if sorted(kinds) != ['propeller', 'rudder']:
        raise ValueError(f'{KIND}: the MMG standard model is for one propeller and one '
                         f'rudder; vessel {spec.name!r} has actuators '
                         f'{dict(zip(spec.actuator_names, kinds, strict=True))}')
    return (spec.control_index(spec.actuators[kinds.index('propeller')].name),
            spec.control_index(spec.actuators[kinds.index('rudder')].name))


class MmgModel(IntegratedModel):
    """MMG forces, the 3x3 mass matrix about midship and RK4 sub-steps per period."""

    kind = KIND

    def __init__(self, spec: VehicleSpec, params: mmg.MmgParams, source: str,
                 substeps: int = 4, terms: Sequence[str] = mmg.FULL_TERMS):
        super().__init__(spec, substeps)
        if spec.state_names != mmg.STATE_NAMES:
            raise ValueError(f'{KIND}: the MMG standard model takes z = {mmg.STATE_NAMES}; '
                             f'vessel {spec.name!r} has {spec.state_names}')
        unknown = [t for t in terms if t not in mmg.TERMS]
        if unknown or not terms:
            raise ValueError(f'{KIND}: terms must be a non-empty subset of '
                             f'{list(mmg.TERMS)}, got {list(terms)}')
        self.propeller_column, self.rudder_column = _control_columns(spec)
        self.params, self.params_source, self.terms = params, source, tuple(terms)

    def derivative(self, z, c):
        """Return [u', v', r'] (m/s^2, m/s^2, rad/s^2) on Array API arrays."""
        xp = namespace(z, c)
        controls = xp.stack([c[..., self.propeller_column], c[..., self.rudder_column]],
                            axis=-1)
        return mmg.derivative(z, controls, self.params, self.terms)

    def describe(self) -> dict:
        """Return the construction arguments, including every parameter value."""
        return {'kind': self.kind, 'params': self.params_source, 'substeps': self.substeps,
                'terms': list(self.terms), 'mmg': asdict(self.params)}


def build_mmg(spec: VehicleSpec, params: str | None = None, values: dict | None = None,
              substeps: int = 4, terms: Sequence[str] | None = None) -> MmgModel:
    """
    Build the MMG model of a vessel.

    Parameter ``values`` win over a file ``params``, which wins over the file the vessel
    description names under ``physics``.
    """
    source = params or spec.physics
    if values:
        loaded = mmg.params_from_dict(values, source=str(source or '<inline mmg>'))
    elif source is None:
        raise ValueError(f'{KIND}: vessel {spec.name!r} names no MMG parameter file (key '
                         f'physics: in its vessel file); give model.physical.params')
    else:
        try:
            path = mmg.find_params_file(source)
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
        if not mmg.is_mmg_file(path):
            raise ValueError(f'{KIND}: {path} is not an MMG parameter file (format: '
                             f'{mmg.FORMAT}); use min, pro or physics for 4-DOF hull files')
        try:
            loaded = mmg.load_mmg(path, spec.length_m, f'vessel {spec.name!r}')
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
    return MmgModel(spec, loaded, str(source), substeps, terms or mmg.FULL_TERMS)
