"""
The quantities a vehicle description may name, with their units and frames.

States are body-frame motion quantities (FRD, SI) and the attitude angles that follow
from them (Euler angles ZYX, Fossen 2021 ch. 2): a vessel moves in the plane (u, v, r;
roll p, phi as a pair), a 6-DOF vehicle adds heave, pitch rate and pitch (w, q, theta)
and always has roll. The dataset also carries the pose (heading and position; height
for a 6-DOF vehicle) that trajectories are measured against. Actuators are of
a few kinds whose model unit is fixed, so a recording's units are converted once, by
the recording map, and never guessed later. Environment inputs expand into the model
columns they feed.
"""

from __future__ import annotations

# name -> (unit, meaning); a description lists its states in this order.
STATES: dict[str, tuple[str, str]] = {
    'u': ('m/s', 'surge velocity, body frame FRD'),
    'v': ('m/s', 'sway velocity, body frame FRD (starboard +)'),
    'w': ('m/s', 'heave velocity, body frame FRD (down +)'),
    'p': ('rad/s', 'roll rate, body frame FRD (starboard down +)'),
    'q': ('rad/s', 'pitch rate, body frame FRD (nose up +)'),
    'r': ('rad/s', 'yaw rate, body frame FRD (turn to starboard +)'),
    'phi': ('rad', 'roll angle (starboard down +)'),
    'theta': ('rad', 'pitch angle (nose up +; ZYX Euler angles, |theta| < pi/2)'),
}
# Sign of each state in the port/starboard mirror image of a motion (the centre plane
# reflects sway, roll and yaw; surge, heave and pitch stay).
STATE_MIRROR: dict[str, float] = {'u': 1.0, 'v': -1.0, 'w': 1.0, 'p': -1.0, 'q': 1.0,
                                  'r': -1.0, 'phi': -1.0, 'theta': 1.0}
# Every vehicle moves in the plane: trajectories integrate these.
PLANAR_STATES = ('u', 'v', 'r')
# Roll is modelled as a pair or not at all.
ROLL_STATES = ('p', 'phi')
# A 6-DOF vehicle (a multirotor): heave, pitch rate and pitch, always with roll.
SPATIAL_STATES = ('w', 'q', 'theta')

POSE: dict[str, tuple[str, str]] = {
    'psi': ('rad', 'heading from north towards east, unwrapped'),
    'x': ('m', "position north of the run's start (NED)"),
    'y': ('m', "position east of the run's start (NED)"),
    'z': ('m', "position down of the run's start (NED; 6-DOF vehicles only)"),
}
# The pose of a vessel in the plane; a 6-DOF vehicle adds its height (z down).
PLANAR_POSE = ('psi', 'x', 'y')

# kind -> (model unit or None for any, meaning)
ACTUATOR_KINDS: dict[str, tuple[str | None, str]] = {
    'propeller': ('rad/s', 'shaft speed, signed: negative turns astern'),
    'rudder': ('rad', 'rudder angle'),
    'azimuth': ('rad', 'azimuth angle of a steerable thruster'),
    'thruster': (None, 'thrust or thrust command of a fixed thruster'),
    'rotor': ('rad/s', 'rotor speed of a multirotor, >= 0 (its spin direction is the '
                       "physics file's)"),
    'other': (None, 'any other control input'),
}

# environment input -> model columns (name, unit, meaning)
ENVIRONMENT: dict[str, tuple[tuple[str, str, str], ...]] = {
    'wind': (
        ('wind_speed', 'm/s', 'measured true wind speed'),
        ('wind_dir_cos', '1', 'cos of the angle the wind comes from, rel. to the bow'),
        ('wind_dir_sin', '1', 'sin of that angle (wind from starboard +)'),
    ),
}

# Sign of each environment column in the mirror image (wind from port becomes starboard).
ENVIRONMENT_MIRROR: dict[str, float] = {'wind_speed': 1.0, 'wind_dir_cos': 1.0,
                                        'wind_dir_sin': -1.0}
# Environment columns a vessel file may give a plausible range in ``limits`` (the
# direction is an angle: any finite value is one).
LIMITED_ENVIRONMENT: dict[str, tuple[str, ...]] = {'wind': ('wind_speed',)}
# Environment columns that are the (cos, sin) of one direction: a unit vector.
ENVIRONMENT_DIRECTIONS: dict[str, tuple[str, str]] = {'wind': ('wind_dir_cos', 'wind_dir_sin')}

# Where a vessel's recordings come from: ``open`` water (wind, waves and currents can act)
# or a ``basin`` (towing tank, model basin: still water, no current).
WATERS: dict[str, str] = {
    'open': 'open water: the sea or a lake, where currents can act',
    'basin': 'a towing tank or model basin: still water, no current',
}
