"""NED/FRD <-> ENU/FLU conversions: exact both ways and as docs/conventions.md says."""

import math

import numpy as np
import pytest

from vessel_physics import frames

RNG = np.random.default_rng(0)


def rot_x(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def rot_y(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def rot_z(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def quat_to_matrix(x, y, z, w):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def test_positions_round_trip_and_examples():
    n, e, d = RNG.normal(size=(3, 50)) * 1000
    x, y, z = frames.position_ned_to_enu(n, e, d)
    np.testing.assert_array_equal((x, y, z), (e, n, -d))
    back = frames.position_enu_to_ned(x, y, z)
    np.testing.assert_array_equal(back, (n, e, d))


def test_heading_round_trip_keeps_unwrapped_values():
    psi = np.linspace(-20.0, 20.0, 101)   # several turns, unwrapped
    yaw = frames.heading_ned_to_enu(psi)
    assert frames.heading_ned_to_enu(0.0) == pytest.approx(math.pi / 2)   # north = +y ENU
    assert frames.heading_ned_to_enu(math.pi / 2) == pytest.approx(0.0)  # east = +x ENU
    np.testing.assert_allclose(frames.heading_enu_to_ned(yaw), psi, rtol=0, atol=1e-14)


def test_twist_round_trip_and_signs():
    u, v, p, r = RNG.normal(size=(4, 20))
    flu = frames.twist_frd_to_flu(u, v, p, r)
    np.testing.assert_array_equal(flu, (u, -v, p, -r))
    np.testing.assert_array_equal(frames.twist_flu_to_frd(*flu), (u, v, p, r))
    np.testing.assert_array_equal(frames.body_flu_to_frd(*frames.body_frd_to_flu(u, v, p)),
                                  (u, v, p))


@pytest.mark.parametrize('phi, theta, psi', [(0.1, 0.0, 0.3), (-0.2, 0.05, 2.5),
                                              (0.0, 0.0, -3.0), (0.3, -0.1, 5.0)])
def test_orientation_matches_the_frame_change(phi, theta, psi):
    # R_enu_flu = P R_ned_frd Q with P: NED -> ENU and Q: FLU -> FRD.
    p_mat = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    q_mat = np.diag([1, -1, -1])
    expected = p_mat @ rot_z(psi) @ rot_y(theta) @ rot_x(phi) @ q_mat
    q = frames.orientation_ned_to_enu(phi, psi, theta)
    np.testing.assert_allclose(quat_to_matrix(*q), expected, atol=1e-12)
    phi2, theta2, psi2 = frames.orientation_enu_to_ned(*q)
    assert phi2 == pytest.approx(phi) and theta2 == pytest.approx(theta, abs=1e-12)
    assert math.remainder(psi2 - psi, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_euler_quaternion_round_trip():
    roll, pitch, yaw = RNG.uniform(-1, 1, (3, 30))
    back = frames.euler_from_quaternion(*frames.quaternion_from_euler(roll, pitch, yaw))
    np.testing.assert_allclose(back, (roll, pitch, yaw), atol=1e-12)


def test_wind_vector_examples_and_round_trip():
    # conventions.md: head wind 5 m/s -> (-5, 0, 0); wind from port -> (0, -5, 0) in FLU.
    np.testing.assert_allclose(frames.wind_to_flu(5.0, 1.0, 0.0), (-5.0, 0.0, 0.0), atol=1e-15)
    np.testing.assert_allclose(frames.wind_to_flu(5.0, 0.0, -1.0), (0.0, -5.0, 0.0),
                               atol=1e-15)
    gamma = RNG.uniform(-math.pi, math.pi, 40)
    speed = RNG.uniform(0.1, 20, 40)
    vx, vy, _ = frames.wind_to_flu(speed, np.cos(gamma), np.sin(gamma))
    s2, c2, n2 = frames.wind_from_flu(vx, vy)
    np.testing.assert_allclose((s2, c2, n2), (speed, np.cos(gamma), np.sin(gamma)),
                               atol=1e-12)


NAMES = ('u', 'v', 'p', 'r', 'phi')


def test_states_go_to_flu_and_back_exactly_and_agree_with_the_twist_and_the_heading():
    z = RNG.normal(size=(4, 7, 5))
    flu = frames.states_frd_to_flu(z, NAMES)
    np.testing.assert_array_equal(frames.states_flu_to_frd(flu, NAMES), z)
    # The twist's map, per state, and roll is one angle in both frames.
    u, v, p, r = frames.twist_frd_to_flu(*z[..., :4].transpose(2, 0, 1))
    np.testing.assert_array_equal(flu[..., :4], np.stack([u, v, p, r], axis=-1))
    np.testing.assert_array_equal(flu[..., 4], z[..., 4])
    roll, _, _ = frames.euler_from_quaternion(*frames.orientation_ned_to_enu(0.2, 0.4))
    assert roll == pytest.approx(0.2)
    # A 3-DOF vessel's states, in its own order.
    np.testing.assert_array_equal(frames.states_frd_to_flu([[1.0, 2.0, 3.0]], 'uvr'),
                                  [[1.0, -2.0, -3.0]])
    # FLU yaw rate is the rate of the ENU heading (a turn to starboard: r > 0 in FRD).
    psi = 0.3 + 0.05 * np.arange(3.0)
    yaw = frames.heading_ned_to_enu(psi)
    r_flu = frames.states_frd_to_flu([[0.0, 0.0, 0.05]], 'uvr')[0, 2]
    np.testing.assert_allclose(np.diff(yaw), r_flu, rtol=1e-12)


def test_an_interval_of_states_keeps_its_order_through_the_frame_change():
    lower = np.array([[-1.0, -2.0, -0.1], [0.5, 0.1, 0.2]])
    upper = lower + np.array([[2.0, 1.0, 0.3]])
    lo, hi = frames.interval_frd_to_flu(lower, upper, 'uvr')
    assert np.all(lo <= hi)
    np.testing.assert_array_equal(lo[:, 0], lower[:, 0])                 # u keeps its sign
    np.testing.assert_array_equal(lo[:, 1:], -upper[:, 1:])              # v, r swap ends
    np.testing.assert_array_equal(hi[:, 1:], -lower[:, 1:])
    back = frames.interval_frd_to_flu(lo, hi, 'uvr')                     # its own inverse
    np.testing.assert_array_equal(back, (lower, upper))
