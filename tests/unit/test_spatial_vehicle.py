"""6-DOF vehicles: the description's vectors, frames and kinematics, the dead reckoning."""

import math

import numpy as np
import pytest

from hybrid_models.metrics import dead_reckoning, trajectory_errors
from vessel_description import parse_vessel
from vessel_description.vessel import VesselError
from vessel_physics import frames
from vessel_physics.integrator import attitude_rates, body_to_ned, kinematics, ned_to_body_3d

SPATIAL = ['u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta']


def spatial_vehicle(**changes):
    data = {'name': 'quad', 'rate_hz': 100.0, 'window_s': 0.5, 'horizon_s': 1.0,
            'states': SPATIAL,
            'actuators': {f'm{i}': {'kind': 'rotor', 'range': [0.0, 3100.0]}
                          for i in range(1, 5)},
            'particulars': {'length_m': 0.1}}
    data.update(changes)
    return parse_vessel(data, 'test')


def test_a_six_dof_vehicle_has_heave_pitch_and_height_in_its_datasets():
    vehicle = spatial_vehicle()
    assert vehicle.is_spatial and vehicle.has_roll
    assert vehicle.pose_names == ('psi', 'x', 'y', 'z')
    assert vehicle.dataset_columns == ('t', *SPATIAL, 'psi', 'x', 'y', 'z',
                                       'm1', 'm2', 'm3', 'm4')
    docs = vehicle.column_docs()
    assert docs['w']['unit'] == 'm/s' and docs['theta']['unit'] == 'rad'
    assert docs['z']['unit'] == 'm' and docs['m1']['unit'] == 'rad/s'
    with pytest.raises(VesselError, match='vessels in the plane; vehicle .quad.'):
        vehicle.require_planar('the zig-zag tool')


def test_vessels_in_the_plane_keep_their_columns():
    boat = spatial_vehicle(states=['u', 'v', 'p', 'r', 'phi'], actuators={
        'n': {'kind': 'propeller', 'range': [0.0, 100.0]}})
    assert not boat.is_spatial
    assert boat.dataset_columns == ('t', 'u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y', 'n')
    boat.require_planar('any tool')


@pytest.mark.parametrize('states', [
    ['u', 'v', 'w', 'r'],                            # heave without roll and pitch
    ['u', 'v', 'w', 'p', 'r', 'phi', 'theta'],       # no pitch rate
    ['u', 'v', 'p', 'q', 'r', 'phi'],                # pitch rate without heave and pitch
])
def test_an_incomplete_six_dof_state_is_refused_in_one_line(states):
    with pytest.raises(VesselError, match='6-DOF vehicle has all of') as err:
        spatial_vehicle(states=states)
    assert '\n' not in str(err.value)


def test_a_rotor_turns_in_rad_per_s_only():
    with pytest.raises(VesselError, match='a rotor is in rad/s'):
        spatial_vehicle(actuators={'m1': {'kind': 'rotor', 'unit': 'rpm',
                                          'range': [0.0, 1.0]}})


def test_flu_signs_of_heave_pitch_rate_and_pitch_follow_the_body_axes_and_orientation():
    signs = frames.state_signs_frd_to_flu(SPATIAL)
    np.testing.assert_array_equal(signs, [1, -1, -1, 1, -1, -1, 1, -1])
    # The pitch sign is the one the orientation conversion uses: nose up in FRD is a
    # negative rotation about FLU's y axis (left).
    qx, qy, qz, qw = frames.orientation_ned_to_enu(0.0, math.pi / 2, 0.3)
    roll, pitch, _ = frames.euler_from_quaternion(qx, qy, qz, qw)
    assert pitch == pytest.approx(-0.3) and roll == pytest.approx(0.0)


def test_attitude_rates_in_closed_form():
    # Level: the Euler rates are the body rates.
    np.testing.assert_allclose(attitude_rates(0.1, 0.2, 0.3, 0.0, 0.0), (0.1, 0.2, 0.3))
    # Rolled 90 deg: a pitch rate turns the heading, a yaw rate lowers the nose.
    phi = math.pi / 2
    np.testing.assert_allclose(attitude_rates(0.0, 0.2, 0.0, phi, 0.0), (0.0, 0.0, 0.2),
                               atol=1e-15)
    np.testing.assert_allclose(attitude_rates(0.0, 0.0, 0.3, phi, 0.0), (0.0, -0.3, 0.0),
                               atol=1e-15)
    # Pitched 60 deg, a yaw rate (body z) turns the heading twice as fast and rolls.
    phi_dot, theta_dot, psi_dot = attitude_rates(0.0, 0.0, 0.3, 0.0, math.pi / 3)
    assert psi_dot == pytest.approx(0.6) and theta_dot == 0.0
    assert phi_dot == pytest.approx(0.3 * math.tan(math.pi / 3))


def test_body_to_ned_is_the_rotation_of_the_orientation_and_inverts():
    rng = np.random.default_rng(0)
    phi, theta, psi = rng.uniform(-1.2, 1.2, (3, 50))
    body = rng.normal(size=(3, 50))
    ned = np.array(body_to_ned(*body, phi, theta, psi))
    np.testing.assert_allclose(ned_to_body_3d(*ned, phi, theta, psi), body, atol=1e-12)
    # The same rotation as the quaternion frames builds (NED/FRD: yaw, pitch, roll).
    for k in range(5):
        x, y, z, w = frames.quaternion_from_euler(phi[k], theta[k], psi[k])
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(rot @ body[:, k], ned[:, k], atol=1e-12)
    # Level and pitch 0, it is the vessels' planar kinematics.
    north, east, down = body_to_ned(1.0, 0.5, 0.0, 0.2, 0.0, 0.7)
    n2, e2, _ = kinematics(1.0, 0.5, 0.0, 0.2, 0.7)
    assert (north, east, down) == pytest.approx((n2, e2, 0.5 * math.sin(0.2)))


def dead_reckon(rows, vehicle=None):
    vehicle = vehicle or spatial_vehicle()
    z = np.zeros((1, len(rows), 8))
    for k, row in enumerate(rows):
        for name, value in row.items():
            z[0, k, SPATIAL.index(name)] = value
    return dead_reckoning(z, vehicle)


def test_hover_stays_at_the_origin():
    xyz, heading = dead_reckon([{}] * 100)
    assert xyz.shape == (1, 100, 3)
    assert not xyz.any() and not heading.any()


def test_a_climb_goes_up_and_a_pitched_flight_goes_forward_and_up():
    xyz, _ = dead_reckon([{'w': -2.0}] * 100)          # body up at level attitude
    np.testing.assert_allclose(xyz[0, -1], (0.0, 0.0, -2.0))
    theta = 0.3
    xyz, _ = dead_reckon([{'u': 1.0, 'theta': theta}] * 100)
    np.testing.assert_allclose(xyz[0, -1], (math.cos(theta), 0.0, -math.sin(theta)),
                               atol=1e-12)


def test_a_constant_yaw_rate_flies_a_circle():
    speed, rate, steps = 2.0, 0.5, 100
    xyz, heading = dead_reckon([{'u': speed, 'r': rate}] * steps)
    assert heading[0, -1] == pytest.approx(rate * 1.0)
    # Forward Euler with the heading held over each step: the chord points of a circle of
    # radius U / r, exact to O(dt) in the heading.
    psi = rate * 0.01 * np.arange(steps)
    expect = 0.01 * speed * np.cumsum(np.stack([np.cos(psi), np.sin(psi)], -1), axis=0)
    np.testing.assert_allclose(xyz[0, :, :2], expect, atol=1e-12)
    radius = speed / rate
    centre = np.array([0.0, radius])
    distance = np.linalg.norm(xyz[0, :, :2] - centre, axis=-1)
    np.testing.assert_allclose(distance, radius, rtol=2e-3)


def test_trajectory_error_is_a_distance_in_space():
    vehicle = spatial_vehicle()
    true = np.zeros((1, 100, 8))
    pred = true.copy()
    pred[..., SPATIAL.index('w')] = 1.0
    pred[..., SPATIAL.index('u')] = 1.0
    err = trajectory_errors(pred, true, vehicle)
    np.testing.assert_allclose(err[0, -1], math.sqrt(2.0))
