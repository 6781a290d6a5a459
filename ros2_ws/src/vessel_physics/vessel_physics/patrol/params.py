"""
The patrol boat's parameters: a frozen dataclass with textbook names, read from YAML.

Naming scheme (Fossen 2011; Perez, Ross & Fossen 2006). A coefficient is the DOF letter
(X surge, Y sway, K roll, N yaw) followed by the factors of its feature in the order the
textbook writes them, with ``a<q>`` meaning ``|q|`` and ``phi`` the roll angle:

=================  ====================  ==========================
textbook           name here             feature
=================  ====================  ==========================
X|u|u              ``Xauu``              ``|u| u``
Y|u|v              ``Yauv``              ``|u| v``
Yv|r|              ``Yvar``              ``v |r|``
Yφ|uv|             ``Yphiauv``           ``phi |u v|``
Nφu|r|             ``Nphiuar``           ``phi u |r|``
Kφφφ               ``Kphiphiphi``        ``phi**3``
Xu' (added mass)   ``Xudot``             coefficient of ``du/dt``
=================  ====================  ==========================

Coordinates are Fossen's FRD body frame with the origin CO on the centre line, midships,
in the waterline (the hull coefficients' reference point); ``xG``, ``zG`` locate the
centre of gravity from CO. All values SI (kg, m, s, N, rad).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from vessel_physics.errors import ConfigError
from vessel_physics.files import check_ranges, numeric_fields, parameter_mapping

GRAVITY = 9.81  # m/s^2, standard value used by the MSS navalvessel data

# Archimedes: a floating hull weighs rho * displacement; files may round m a little.
MASS_TOLERANCE = 0.01
FORMAT = 'patrol-params/1'   # optional in a file: parameter files older than it have none


@dataclass(frozen=True)
class PatrolParams:
    """Parameters of one 4-DOF (surge, sway, roll, yaw) vessel model; SI units, FRD frame."""

    name: str
    # Particulars and rigid body
    rho: float          # water density, kg/m^3
    m: float            # mass, kg
    displacement: float  # displaced volume nabla, m^3
    GM: float           # transverse metacentric height, m
    Ixx: float          # roll inertia about CO, kg m^2
    Izz: float          # yaw inertia about CO, kg m^2
    xG: float           # centre of gravity forward of CO, m
    zG: float           # centre of gravity below CO (negative = above), m
    Lpp: float          # length between perpendiculars, m
    B: float            # beam, m
    T: float            # draught, m
    # Added mass (Perez, Ross & Fossen 2006)
    Xudot: float
    Yvdot: float
    Ypdot: float
    Yrdot: float
    Kvdot: float
    Kpdot: float
    Krdot: float
    Nvdot: float
    Npdot: float
    Nrdot: float
    # Hull damping and cross-flow (Blanke & Christensen 1993 via Perez et al. 2006)
    Xauu: float
    Xvr: float
    Yauv: float
    Yur: float
    Yvav: float
    Yvar: float
    Yrav: float
    Yphiauv: float
    Yphiaur: float
    Yphiuu: float
    Kauv: float
    Kur: float
    Kvav: float
    Kvar: float
    Krav: float
    Kphiauv: float
    Kphiaur: float
    Kphiuu: float
    Kaup: float
    Kpap: float
    Kp: float
    Kphiphiphi: float
    Nauv: float
    Naur: float
    Nrar: float
    Nrav: float
    Nphiauv: float
    Nphiuar: float
    Nphiuau: float
    # Twin rudder-propellers on one shaft speed (Baier et al. Pro model)
    prop_diameter: float   # m
    wake_fraction: float   # 1
    KT0: float             # KT(J) = KT0 + KT1 J + KT2 J^2
    KT1: float
    KT2: float
    prop_lx: float         # propeller x from CO, m (negative = aft)
    prop_ly: float         # lateral distance of each unit from the centre line, m (> 0)
    prop_lz: float         # propeller z from CO, m (positive = below)
    # Actuators
    rudder_max_angle: float      # rad
    rudder_max_rate: float       # rad/s
    rudder_time_constant: float  # s
    shaft_max_speed: float       # rad/s
    shaft_max_accel: float       # rad/s^2
    shaft_time_constant: float   # s
    # Above-water geometry for Isherwood (1972) wind loads
    Loa: float        # length over all, m
    AL: float         # lateral projected area, m^2
    AF: float         # frontal projected area, m^2
    ASS: float        # lateral projected area of the superstructure, m^2
    wind_S: float     # perimeter of the lateral projection (no waterline, masts), m
    wind_C: float     # distance from the bow of the lateral-area centroid, m
    wind_M: float     # number of distinct groups of masts or king posts
    wind_height: float  # lateral-area centroid above CO, m (K_wind = wind_height * Y_wind)

    @property
    def restoring_roll(self) -> float:
        """Linear roll restoring coefficient rho g nabla GM (N m/rad)."""
        return self.rho * GRAVITY * self.displacement * self.GM


FLOAT_FIELDS = tuple(f.name for f in fields(PatrolParams) if f.name != 'name')
_POSITIVE = ('rho', 'm', 'displacement', 'GM', 'Ixx', 'Izz', 'Lpp', 'B', 'T',
             'prop_diameter', 'prop_ly', 'rudder_max_angle', 'rudder_max_rate',
             'rudder_time_constant', 'shaft_max_speed', 'shaft_max_accel',
             'shaft_time_constant', 'Loa', 'AL', 'AF', 'wind_S', 'wind_C')


def _validated(params: PatrolParams, source: str) -> PatrolParams:
    check_ranges(params, FLOAT_FIELDS, _POSITIVE, ('wake_fraction',), source)
    archimedes = params.rho * params.displacement
    if abs(params.m - archimedes) > MASS_TOLERANCE * params.m:
        raise ConfigError(f'{source}: m: must equal rho * displacement = {archimedes:.6g} kg '
                          f'within {MASS_TOLERANCE:.0%} (a floating hull), got {params.m!r}')
    return params


def params_from_dict(data, source: str = 'patrol parameters') -> PatrolParams:
    """Build validated parameters from a mapping with exactly the dataclass's keys."""
    data = parameter_mapping(data, FORMAT, source)
    values = numeric_fields(data, (f.name for f in fields(PatrolParams)), FLOAT_FIELDS,
                            source, 'parameters')
    return _validated(PatrolParams(name=str(data['name']), **values), source)
