"""Force terms against hand-computed cases; numpy and torch give the same numbers."""

import math

import numpy as np
import pytest
import torch

from vessel_physics.arrays import stack_last
from vessel_physics.family import Physics
from vessel_physics.integrator import kinematics, rk4_step
from vessel_physics.patrol import forces as terms
from vessel_physics.patrol.family import FAMILY, PRO_TERMS, SIMULATOR_TERMS, TERMS, mass_matrix
from vessel_physics.patrol.wind_loads import wind_force
from vessel_physics.physics_file import load_physics
from vessel_physics.simulation.actuators import servo_rate

P = load_physics('patrol_vessel').params   # literal numbers below are this file's values
FORCES = sorted(n for n, t in TERMS.items() if t.kind == 'force')


def total_force(names, z, c):
    return Physics(FAMILY, P, tuple(names)).force(z, c)


def accelerations(tau):
    return Physics(FAMILY, P, ()).rates(tau, tau)[..., :4]


def rudder_rate(command, angle, params):
    return servo_rate(command, angle, -params.rudder_max_angle, params.rudder_max_angle,
                      params.rudder_time_constant, params.rudder_max_rate)


def shaft_accel(command, speed, params):
    return servo_rate(command, speed, 0.0, params.shaft_max_speed, params.shaft_time_constant,
                      params.shaft_max_accel)
G = 9.81
RPM = 2 * math.pi / 60


def z_of(u=0.0, v=0.0, p=0.0, r=0.0, phi=0.0):
    return np.array([[u, v, p, r, phi]])


def c_of(n=0.0, dp=0.0, ds=0.0, speed=0.0, gamma=0.0):
    return np.array([[n, dp, ds, speed, math.cos(gamma), math.sin(gamma)]])


def test_rigid_body_coriolis_by_hand():
    u, v, p, r = 2.0, 0.5, 0.1, 0.05
    m, xg, zg = 362000.0, -3.38, -1.06
    expected = [m * (v * r + xg * r * r - zg * p * r), -m * u * r, m * zg * u * r,
                -m * xg * u * r]
    # X = 362000 (0.025 - 0.00845 + 0.0053) = 7909.7 N
    assert expected[0] == pytest.approx(7909.7)
    got = terms.rigid_body_coriolis(z_of(u, v, p, r), c_of(), P)[0]
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_restoring_by_hand():
    phi = 0.1
    linear = 1014.0 * 9.81 * 357.0 * 1.1 * phi          # 390,632 N m
    cubic = -0.325 * 362000.0 * 9.81 * phi ** 3
    got = terms.restoring(z_of(phi=phi), c_of(), P)[0]
    np.testing.assert_allclose(got, [0, 0, -linear + cubic, 0], rtol=1e-9, atol=1e-9)
    got_lin = terms.restoring_linear(z_of(phi=phi), c_of(), P)[0]
    np.testing.assert_allclose(got_lin, [0, 0, -linear, 0], rtol=1e-12, atol=1e-9)
    assert linear == pytest.approx(390632.0, abs=1.0)


def test_hull_damping_by_hand():
    u, v, p, r, phi = 5.0, -0.3, 0.02, 0.01, 0.05
    x = -1960 * abs(u) * u + 119460 * v * r
    y = (-11800 * abs(u) * v + 131000 * u * r - 3700 * v * abs(v) - 794000 * v * abs(r)
         - 182000 * r * abs(v) + 10800 * phi * abs(u * v) + 251000 * phi * abs(u * r)
         - 74 * phi * u * u)
    k = (9260 * abs(u) * v - 102000 * u * r + 29300 * v * abs(v) + 621000 * v * abs(r)
         + 142000 * r * abs(v) - 8400 * phi * abs(u * v) - 196000 * phi * abs(u * r)
         - 1180 * phi * u * u - 15500 * abs(u) * p - 416000 * p * abs(p) - 500000 * p)
    n = (-92000 * abs(u) * v - 4.71e6 * abs(u) * r - 202e6 * r * abs(r) - 15.6e6 * r * abs(v)
         - 214000 * phi * abs(u * v) - 4.98e6 * phi * u * abs(r) - 8000 * phi * u * abs(u))
    got = terms.hull_damping(z_of(u, v, p, r, phi), c_of(), P)[0]
    np.testing.assert_allclose(got, [x, y, k, n], rtol=1e-12)


def test_the_numpy_hull_features_are_the_term_formulas_bit_for_bit():
    """The simulator's gathered features: every HULL_TERMS product, row-major, same bits."""
    rng = np.random.default_rng(4)
    z = rng.normal(size=(257, 5)) * [3.0, 1.0, 0.2, 0.1, 0.3]
    z[0], z[1], z[2, 0] = 0.0, -0.0, -7.5
    states = {name: z[:, i] for i, name in enumerate(terms.Z_COLUMNS)}
    formulas = np.stack(terms.hull_terms(terms.HULL_DAMPING_FEATURES, states), axis=-1)
    gathered = terms.hull_damping_features(z)
    assert gathered.view(np.int64).tolist() == formulas.view(np.int64).tolist()
    # the layout decides OpenBLAS's path through the product with the coefficients
    assert gathered.flags['C_CONTIGUOUS']
    matrix = terms.hull_damping_matrix(P)
    assert np.array_equal(gathered @ matrix, formulas @ matrix)
    torch_features = terms.hull_damping_features(torch.as_tensor(z))
    assert np.array_equal(torch_features.numpy(), formulas)


def test_stack_last_is_np_stack_on_the_last_axis():
    parts = [np.arange(6.0).reshape(2, 3) * k for k in (1.0, -2.0, 0.5)]
    stacked = stack_last(parts, np)
    assert np.array_equal(stacked, np.stack(parts, axis=-1)) and stacked.flags['C_CONTIGUOUS']
    tensors = [torch.as_tensor(p) for p in parts]
    assert torch.equal(stack_last(tensors, torch), torch.stack(tensors, dim=-1))


def test_propulsion_by_hand():
    u, v, n_rpm, d_port, d_stbd = 8.0, 0.2, 900.0, 0.10, 0.05
    rps = n_rpm / 60.0
    forces = []
    for d in (d_port, d_stbd):
        va = 0.75 * (u * math.cos(d) + v * math.sin(d))
        j = va / (rps * 0.972)
        kt = 0.4594 - 0.3246 * j - 0.1060 * j * j
        t = 1014.0 * 0.972 ** 4 * rps ** 2 * kt
        forces.append((t * math.cos(d), t * math.sin(d)))
    (fxp, fyp), (fxs, fys) = forces
    expected = [fxp + fxs, fyp + fys, -4.0 * (fyp + fys), -25.0 * (fyp + fys) + 4.0 * (fxp - fxs)]
    got = terms.propulsion(z_of(u, v), c_of(n_rpm * RPM, d_port, d_stbd), P)[0]
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    # Positive rudder: thrust to starboard, bow to port (N < 0), heel to port (K < 0).
    assert got[1] > 0 and got[3] < 0 and got[2] < 0


def test_propulsion_gives_no_thrust_at_zero_shaft_speed_or_huge_advance():
    assert np.all(terms.propulsion(z_of(5.0), c_of(0.0), P) == 0)
    assert np.all(terms.propulsion(z_of(30.0), c_of(400 * RPM), P) == 0)   # KT(J) < 0


def test_wind_beam_from_port_by_hand():
    # Wind from port (gamma = -90 deg) at 10 m/s on a hull at rest. Isherwood 90-deg rows:
    # CY = 0.889 + 0.138 (2 AF / B^2) - 0.66 (C / L); CX = -(0.355 - 0.247 S/L + 0.018 M);
    # CN = 0.2627 - 0.508 C/L. The side force pushes to starboard and, acting above CO,
    # heels the hull to starboard (leeward): K = h Y > 0.
    q = 0.5 * 1.224 * 10.0 ** 2
    cy = 0.889 + 0.138 * (2 * 70 / 8.6 ** 2) - 0.66 * (28 / 56)
    cx = -(0.355 - 0.247 * (90 / 56) + 0.018 * 1)
    cn = 0.2627 - 0.508 * (28 / 56)
    y = q * cy * 260.0
    expected = [q * cx * 70.0, y, 3.2 * y, q * cn * 260.0 * 56.0]
    got = wind_force(z_of(), c_of(speed=10.0, gamma=-math.pi / 2), P)[0]
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    assert got[1] > 0 and got[2] > 0


@pytest.mark.parametrize('gamma, sign_x', [(0.0, -1), (math.pi, +1)])
def test_wind_head_and_tail(gamma, sign_x):
    got = wind_force(z_of(), c_of(speed=10.0, gamma=gamma), P)[0]
    assert np.sign(got[0]) == sign_x
    assert abs(got[1]) < 1e-9 and abs(got[3]) < 1e-9


def test_wind_from_starboard_bow_turns_the_bow_to_port():
    got = wind_force(z_of(), c_of(speed=10.0, gamma=math.radians(30)), P)[0]
    assert got[1] < 0 and got[3] < 0 and got[2] < 0


def test_wind_interpolates_linearly_between_nodes():
    mid = wind_force(z_of(), c_of(speed=8.0, gamma=math.radians(45)), P)[0]
    lo = wind_force(z_of(), c_of(speed=8.0, gamma=math.radians(40)), P)[0]
    hi = wind_force(z_of(), c_of(speed=8.0, gamma=math.radians(50)), P)[0]
    np.testing.assert_allclose(mid, 0.5 * (lo + hi), rtol=1e-12)


def test_apparent_wind_of_forward_speed_is_a_head_wind():
    moving = wind_force(z_of(u=10.0), c_of(), P)[0]
    head = wind_force(z_of(), c_of(speed=10.0), P)[0]
    np.testing.assert_allclose(moving, head, rtol=1e-12)


def test_mass_matrix_rows_and_inverse():
    m = mass_matrix(P)
    assert m[1, 2] == pytest.approx(-(362000 * -1.06 - 296000))
    assert m[2, 1] == pytest.approx(-(362000 * -1.06 + 296000))
    assert m[3, 3] == pytest.approx(47.934e6 + 38.7e6)
    tau = np.array([[1e4, -2e4, 3e5, -4e6]])
    np.testing.assert_allclose(accelerations(tau)[0], np.linalg.solve(m, tau[0]),
                               rtol=1e-12)


def test_registry_composes_by_name():
    z, c = z_of(6.0, 0.1, 0.01, 0.02, 0.03), c_of(800 * RPM, 0.05, 0.05, 5.0, 1.0)
    total = total_force(PRO_TERMS, z, c)
    parts = sum(TERMS[n].fn(z, c, P) for n in ('rigid_body_coriolis',
                                               'restoring_linear', 'propulsion'))
    np.testing.assert_allclose(total, parts, rtol=1e-12)
    assert set(SIMULATOR_TERMS) <= set(FORCES)
    assert TERMS['restoring'].dofs == ('K',)
    assert TERMS['wind'].velocity == 'ground'
    with pytest.raises(KeyError, match='unknown term'):
        total_force(['nope'], z, c)
    assert terms.roll_natural_frequency(P) == pytest.approx(1.11, abs=0.02)


def random_inputs(rng, n=16):
    z = np.column_stack([rng.uniform(-2, 10, n), rng.uniform(-1, 1, n),
                         rng.uniform(-0.1, 0.1, n), rng.uniform(-0.05, 0.05, n),
                         rng.uniform(-0.2, 0.2, n)])
    gamma = rng.uniform(-math.pi, math.pi, n)
    c = np.column_stack([rng.uniform(0, 100, n), rng.uniform(-0.4, 0.4, n),
                         rng.uniform(-0.4, 0.4, n), rng.uniform(0, 15, n), np.cos(gamma),
                         np.sin(gamma)])
    return z, c


@pytest.mark.parametrize('name', FORCES)
def test_numpy_and_torch_agree_and_gradients_flow(name):
    z, c = random_inputs(np.random.default_rng(0))
    fn = TERMS[name].fn
    expected = fn(z, c, P)
    zt = torch.tensor(z, dtype=torch.float64, requires_grad=True)
    ct = torch.tensor(c, dtype=torch.float64, requires_grad=True)
    got = fn(zt, ct, P)
    assert got.dtype == torch.float64 and got.shape == (16, 4)
    np.testing.assert_allclose(got.detach().numpy(), expected, rtol=1e-12, atol=1e-9)
    got.sum().backward()
    grads = torch.cat([g.flatten() for g in (zt.grad, ct.grad) if g is not None])
    assert torch.isfinite(grads).all() and grads.abs().sum() > 0


def test_model_helpers_run_on_torch():
    z, c = random_inputs(np.random.default_rng(1))
    zt, ct = torch.tensor(z), torch.tensor(c)
    tau = total_force(SIMULATOR_TERMS, zt, ct)
    np.testing.assert_allclose(accelerations(tau).numpy(),
                               accelerations(tau.numpy()), rtol=1e-12)
    kin = kinematics(zt[:, 0], zt[:, 1], zt[:, 3], zt[:, 4], zt[:, 2] * 10)
    kin_np = kinematics(z[:, 0], z[:, 1], z[:, 3], z[:, 4], z[:, 2] * 10)
    for a, b in zip(kin, kin_np, strict=True):
        np.testing.assert_allclose(a.numpy(), b, rtol=1e-12)
    np.testing.assert_allclose(rudder_rate(ct[:, 1], ct[:, 2], P).numpy(),
                               rudder_rate(c[:, 1], c[:, 2], P), rtol=1e-12)
    np.testing.assert_allclose(shaft_accel(ct[:, 0], ct[:, 0] * 0.5, P).numpy(),
                               shaft_accel(c[:, 0], c[:, 0] * 0.5, P), rtol=1e-12)


def test_actuators_by_hand():
    # 0.1 rad error / 0.2 s = 0.5 rad/s, limited to 20 deg/s; order beyond 45 deg is clipped.
    assert rudder_rate(np.array(0.1), np.array(0.0), P) == pytest.approx(math.radians(20))
    assert rudder_rate(np.array(0.01), np.array(0.0), P) == pytest.approx(0.05)
    assert rudder_rate(np.array(2.0), np.array(P.rudder_max_angle), P) == 0.0
    assert shaft_accel(np.array(50.0), np.array(49.0), P) == pytest.approx(1.0)
    assert shaft_accel(np.array(100.0), np.array(0.0), P) == pytest.approx(40 * RPM)
    assert shaft_accel(np.array(-5.0), np.array(0.0), P) == pytest.approx(0.0)


def test_kinematics_and_rk4_by_hand():
    dx, dy, dpsi = kinematics(np.array(2.0), np.array(1.0), np.array(0.1), np.array(0.2),
                              np.array(math.pi / 2))
    assert dx == pytest.approx(-math.cos(0.2))       # u cos psi - v cos phi sin psi
    assert dy == pytest.approx(2.0)                   # u sin psi + v cos phi cos psi
    assert dpsi == pytest.approx(0.1 * math.cos(0.2))
    # RK4 is exact to 4th order: x' = -x over 1 s in 10 steps.
    x = np.array(1.0)
    for i in range(10):
        x = rk4_step(lambda t, s: -s, i * 0.1, x, 0.1)
    assert x == pytest.approx(math.exp(-1.0), rel=1e-6)
