"""
The Fossen matrix family and the Otter USV against published figures and by hand.

Published figures of the Otter (Maritime Robotics; the parameters of Fossen's
PythonVehicleSimulator, vehicles/otter.py): a top speed of 6 knots when both propellers
give their bollard pull of 24.4 kgf together (13.6 kgf astern), and time constants of
1 s in sway and yaw. Turning: steady states under differential thrust from
PythonVehicleSimulator's own (6-DOF) otter.py, run for 120 s with its Euler step at
5 ms (the command is in the docstring of ``PVS_TURNS``); our horizontal-plane model
leaves out heave, roll and pitch, whose trim gives the 6-DOF craft a forward component
of the payload's weight (it makes 6.26 kn at full thrust): yaw rates agree within 4 %,
speeds within 8 %.
"""

import math

import numpy as np
import pytest
import torch

from vessel_description import load_vessel
from vessel_physics.errors import ConfigError
from vessel_physics.fossen import FAMILY, forces
from vessel_physics.integrator import free_run
from vessel_physics.physics_file import load_physics

OTTER = load_vessel('otter')
PHYSICS = load_physics(OTTER.physics, OTTER)
P = PHYSICS.params
G = 9.81
KNOT = 0.5144
N_MAX = math.sqrt(0.5 * 24.4 * G / P.thrusters[0].k_forward)   # rad/s, full bollard pull
# (port n, starboard n) rad/s -> (u m/s, v m/s, r rad/s) at steady state in otter.py:
# otter().dynamics with attitudeEuler, h = 0.005 s, 120 s from rest; speeds above n_max
# saturate there, so they are given at n_max.
PVS_TURNS = {(80.0, 103.93): (2.4190, 0.2622, -0.2880),
             (60.0, 100.0): (1.9353, 0.2063, -0.2726),
             (100.0, -50.0): (1.2337, -0.1452, 0.3010),
             (50.0, 90.0): (1.5457, 0.1473, -0.2291),
             (90.0, 0.0): (1.1923, -0.1232, 0.2509)}


def steady(n_port: float, n_stbd: float, seconds: float = 40.0) -> np.ndarray:
    """Return (u, v, r) after ``seconds`` (time constants near 1 s) at constant shaft speeds."""
    c = np.tile([n_port, n_stbd], (1, int(seconds * 10), 1)).astype(float)
    return free_run(PHYSICS.derivative, np.zeros((1, 3)), c, 0.1, 2)[0, -1]


def test_full_bollard_pull_is_the_published_24_4_and_13_6_kgf():
    forward = forces.thrusters(np.zeros((1, 3)), np.array([[N_MAX, N_MAX]]), P)[0]
    assert forward[0] == pytest.approx(24.4 * G, rel=1e-9) and forward[2] == 0.0
    n_min = -math.sqrt(0.5 * 13.6 * G / P.thrusters[0].k_reverse)
    astern = forces.thrusters(np.zeros((1, 3)), np.array([[n_min, n_min]]), P)[0]
    assert astern[0] == pytest.approx(-13.6 * G, rel=1e-9)
    assert OTTER.actuator('n_port').high == pytest.approx(N_MAX, abs=0.05)
    assert OTTER.actuator('n_port').low == pytest.approx(n_min, abs=0.05)


def test_top_speed_is_six_knots_at_full_thrust_and_goes_with_the_thrust():
    assert steady(N_MAX, N_MAX)[0] == pytest.approx(6 * KNOT, rel=2e-3)
    # Linear surge damping: half the thrust, half the speed; straight, no sway or yaw.
    half = steady(N_MAX / math.sqrt(2), N_MAX / math.sqrt(2))
    assert half[0] == pytest.approx(3 * KNOT, rel=2e-3)
    assert abs(half[1]) < 1e-9 and abs(half[2]) < 1e-9


@pytest.mark.parametrize('orders', sorted(PVS_TURNS))
def test_steady_turns_match_python_vehicle_simulator(orders):
    u, v, r = steady(*orders)
    ref_u, ref_v, ref_r = PVS_TURNS[orders]
    assert r == pytest.approx(ref_r, rel=0.04)
    assert u == pytest.approx(ref_u, rel=0.08) and u < ref_u    # no trim: a little slower
    assert np.sign(v) == np.sign(ref_v) and v == pytest.approx(ref_v, rel=0.15)
    # The faster thruster is the outer one: more starboard thrust turns the bow to port.
    assert np.sign(r) == np.sign(orders[0] - orders[1])


def test_time_constants_of_one_second_in_sway_and_yaw():
    m = PHYSICS.mass_matrix()
    assert m[1, 1] / -P.Yv == pytest.approx(1.0) and m[2, 2] / -P.Nr == pytest.approx(1.0)
    # At rest, a small sway or yaw decays on the linear damping's time scale.
    for i, small in ((1, 0.002), (2, 0.0005)):
        z0 = np.zeros((1, 3))
        z0[0, i] = small
        run = free_run(PHYSICS.derivative, z0, np.zeros((1, 100, 2)), 0.01, 1)[0]
        tau = np.interp(math.exp(-1.0), run[::-1, i] / small, np.arange(101)[::-1] * 0.01)
        assert 0.7 < tau < 1.3, (i, tau)      # coupled through x_G m: near, not exactly, 1 s


def test_coriolis_and_munk_moment_by_hand():
    u, v, r = 2.0, 0.3, 0.2
    z = np.array([[u, v, r]])
    m, xg = P.m, P.x_G
    np.testing.assert_allclose(forces.rigid_body_coriolis(z, None, P)[0],
                               [m * (v * r + xg * r * r), -m * u * r, -m * xg * u * r])
    a11, a22 = -P.Xudot, -P.Yvdot
    np.testing.assert_allclose(forces.added_mass_coriolis(z, None, P)[0],
                               [a22 * v * r, -a11 * u * r, (a11 - a22) * u * v])
    # Kinetic energy is conserved by the Coriolis forces: nu . C(nu) nu = 0.
    total = forces.rigid_body_coriolis(z, None, P) + forces.added_mass_coriolis(z, None, P)
    assert abs(float(total[0] @ z[0])) < 1e-9


def test_crossflow_of_pure_sway_and_pure_yaw():
    k = 0.5 * P.rho * P.crossflow_draft * P.crossflow_Cd
    length = P.crossflow_length
    sway = forces.crossflow(np.array([[0.0, 0.4, 0.0]]), None, P)[0]
    assert sway[1] == pytest.approx(-k * length * 0.16, rel=1e-12) and sway[2] == \
        pytest.approx(0.0, abs=1e-12)
    # Pure yaw: N = -k r|r| int x^3 sign(x) dx = -k r|r| L^4 / 32 (midpoint rule: 0.3 %).
    yaw = forces.crossflow(np.array([[0.0, 0.0, 0.5]]), None, P)[0]
    assert yaw[2] == pytest.approx(-k * 0.25 * length ** 4 / 32, rel=5e-3)
    assert yaw[1] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize('name', sorted(n for n, t in FAMILY.terms.items() if t.kind == 'force'))
def test_numpy_and_torch_agree_and_gradients_flow(name):
    rng = np.random.default_rng(0)
    z = np.column_stack([rng.uniform(-1, 3, 8), rng.uniform(-0.5, 0.5, 8),
                         rng.uniform(-0.4, 0.4, 8)])
    c = np.column_stack([rng.uniform(-100, 100, 8), rng.uniform(-100, 100, 8)])
    fn = FAMILY.terms[name].fn
    expected = fn(z, c, P)
    zt = torch.tensor(z, requires_grad=True)
    got = fn(zt, torch.tensor(c), P)
    np.testing.assert_allclose(got.detach().numpy(), expected, rtol=1e-12, atol=1e-12)
    if got.requires_grad:
        got.sum().backward()
        assert torch.isfinite(zt.grad).all()


def test_rudders_and_wind_by_position():
    data = FAMILY.parameter_values(P)
    data.update(rudders=[{'actuator': 'delta', 'x': -1.0, 'y': 0.0, 'area': 0.05,
                          'lift_slope': 3.0, 'max_rate': 0.5, 'time_constant_s': 0.1}],
                wind_AF=0.5, wind_AL=1.5, wind_cx=0.6, wind_cy=0.9, wind_cn=0.1)
    params = FAMILY.read_parameters(data, 'test')
    c = np.array([[50.0, 50.0, 0.2, 6.0, 0.0, 1.0]])   # rudder 0.2 rad; wind from starboard
    rudder = forces.rudders(np.array([[2.0, 0.0, 0.0]]), c, params)[0]
    assert rudder[1] < 0 < rudder[2] and rudder[0] < 0   # stern to port: bow to starboard
    wind = forces.wind(np.zeros((1, 3)), c, params)[0]
    assert wind[1] < 0                                   # pushed to port
    assert np.all(forces.wind(np.zeros((1, 3)), c[:, :3], params) == 0)   # no wind input


def test_a_vessel_whose_actuators_the_parameters_do_not_drive_is_refused():
    data = OTTER.to_dict()
    data['actuators'][1]['name'] = 'n_starboard'
    data.pop('mirror')
    from vessel_description import parse_vessel
    with pytest.raises(ConfigError, match="drive a propeller 'n_stbd'"):
        load_physics(OTTER.physics).for_vessel(parse_vessel(data))
