"""Min and Pro against hand-computed cases (nominal vessel parameters)."""

import math

import numpy as np
import pytest
import torch

from hybrid_models.physical import build_physical
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

vp = pytest.importorskip('vessel_physics.physics_file')
P = vp.load_physics('nominal_vessel').params
M = np.array([
    [P.m - P.Xudot, 0, 0, 0],
    [0, P.m - P.Yvdot, -(P.m * P.zG + P.Ypdot), P.m * P.xG - P.Yrdot],
    [0, -(P.m * P.zG + P.Kvdot), P.Ixx - P.Kpdot, -P.Krdot],
    [0, P.m * P.xG - P.Nvdot, -P.Npdot, P.Izz - P.Nrdot],
])
MINV = np.linalg.inv(M)
K_ROLL = P.rho * 9.81 * P.displacement * P.GM


def model(kind, substeps=10):
    return build_physical({'kind': kind, 'substeps': substeps}, SHIP)


def t(*rows):
    return torch.tensor(rows, dtype=torch.float64)


def test_min_derivative_is_coriolis_plus_linear_restoring():
    u, v, p, r, phi = 6.0, 0.3, 0.02, -0.03, 0.04
    m, xg, zg = P.m, P.xG, P.zG
    tau = np.array([m * (v * r + xg * r * r - zg * p * r), -m * u * r, m * zg * u * r
                    - K_ROLL * phi, -m * xg * u * r])
    expected = np.concatenate([MINV @ tau, [p]])     # phi' = p, the roll RATE
    got = model('min').derivative(t([u, v, p, r, phi]), t([80, 0.1, 0.1, 5, 0, 1]))
    np.testing.assert_allclose(got[0].numpy(), expected, rtol=1e-10)


def test_min_ignores_controls_and_rests_at_zero():
    out = model('min')(t([0, 0, 0, 0, 0]), t([100, 0.05, -0.05, 10, 0.5, 0.8]))
    assert torch.equal(out, torch.zeros(1, 5, dtype=torch.float64))


def test_min_roll_is_the_linear_oscillator_over_one_second():
    # u = 0: no Coriolis on Y, K, N, so p' = -w^2 phi with w^2 = K_ROLL * Minv[p, p]
    # (sway and yaw follow through the mass coupling but do not feed back).
    w = math.sqrt(K_ROLL * MINV[2, 2])
    phi0, p0 = 0.05, 0.01
    out = model('min')(t([0, 0, p0, 0, phi0]), t([0] * 6))[0].numpy()
    phi1 = phi0 * math.cos(w) + p0 / w * math.sin(w)
    p1 = -phi0 * w * math.sin(w) + p0 * math.cos(w)
    assert out[4] == pytest.approx(phi1, rel=1e-6)
    assert out[2] == pytest.approx(p1, rel=1e-6)
    # Sway velocity integrates Minv[v, p] * (-K_ROLL phi).
    v1 = -K_ROLL * MINV[1, 2] * (phi0 * math.sin(w) / w + p0 / w ** 2 * (1 - math.cos(w)))
    assert out[1] == pytest.approx(v1, rel=1e-6)


def test_sub_steps_converge_and_one_euler_step_would_not():
    z, c = t([6, 0.2, 0.03, 0.02, 0.05]), t([0] * 6)
    fine, coarse = model('min', 40)(z, c), model('min', 4)(z, c)
    # RK4 at h = 0.25 s (the default) is within 1e-5 of the converged step: far below
    # the measurement noise; explicit Euler at 1 s (the authors' choice) is not.
    assert (fine - coarse).abs().max() < 1e-5
    euler = z + model('min').derivative(z, c)
    assert (euler - fine).abs().max() > 1e-3


def thrust(u, n_rad_s, delta):
    n = n_rad_s / (2 * math.pi)
    va = max(0.0, (1 - P.wake_fraction) * u * math.cos(delta))
    j = va / (n * P.prop_diameter)
    kt = P.KT0 + P.KT1 * j + P.KT2 * j * j
    return max(0.0, P.rho * P.prop_diameter ** 4 * n * n * kt)


def test_pro_adds_the_twin_propeller_thrust():
    u, n = 6.0, 90.0
    base = model('min').derivative(t([u, 0, 0, 0, 0]), t([n, 0, 0, 0, 1, 0]))
    pro = model('pro').derivative(t([u, 0, 0, 0, 0]), t([n, 0, 0, 0, 1, 0]))
    tau = np.array([2 * thrust(u, n, 0.0), 0, 0, 0])
    np.testing.assert_allclose((pro - base)[0, :4].numpy(), MINV @ tau, rtol=1e-10)


def test_pro_rudders_push_the_stern_to_starboard_and_turn_to_port():
    u, n, d = 6.0, 90.0, 0.05
    z, c = t([u, 0, 0, 0, 0]), t([n, d, d, 0, 1, 0])
    diff = (model('pro').derivative(z, c) - model('min').derivative(z, c))[0, :4].numpy()
    fy = 2 * thrust(u, n, d) * math.sin(d)
    fx = 2 * thrust(u, n, d) * math.cos(d)
    tau = np.array([fx, fy, -P.prop_lz * fy, P.prop_lx * fy])
    np.testing.assert_allclose(diff, MINV @ tau, rtol=1e-9)
    assert tau[3] < 0                                    # bow to port: negative yaw moment
    assert model('pro')(z, c)[0, 3] < 0


def test_physics_is_differentiable_and_batched():
    z = t([6, 0.1, 0.01, 0.01, 0.02], [3, -0.1, 0, 0.02, -0.01]).requires_grad_(True)
    out = model('pro+lin', 4)(z, t([80, 0.02, 0.02, 2, 1, 0], [60, 0, 0, 1, 0, 1]))
    out.sum().backward()
    assert out.shape == (2, 5) and torch.isfinite(z.grad).all()
