"""The MMG standard model (vessel_physics.mmg) against shipmmg and against the paper."""

import math

import numpy as np
import pytest
import torch

from vessel_physics.errors import ConfigError
from vessel_physics.family import Physics
from vessel_physics.files import config_dir
from vessel_physics.mmg import FAMILY
from vessel_physics.mmg import forces as mmg
from vessel_physics.mmg.family import inverse_mass_matrix_t
from vessel_physics.mmg.params import HULL_N, HULL_X, HULL_Y, MmgParams
from vessel_physics.mmg.zigzag import zigzag
from vessel_physics.physics_file import load_physics

shipmmg = pytest.importorskip('shipmmg.mmg_3dof', reason='shipmmg is the reference model')

PUBLISHED = config_dir() / 'kvlcc2_mmg_yasukawa2015.yaml'
REV_PER_S = 17.95            # Yasukawa & Yoshimura's KVLCC2 model propeller speed
SERVICE_SPEED = 1.179        # m/s, the 7 m model's approach speed


def physics(params: MmgParams) -> Physics:
    """Return the MMG model of the parameters, in the family's vectors (c = [n, delta])."""
    return Physics(FAMILY, params, FAMILY.model_terms)


@pytest.fixture(scope='module')
def published():
    return load_physics(PUBLISHED).params


@pytest.fixture(scope='module')
def as_shipmmg(published):
    """
    Return the published set in the two points where shipmmg departs from the paper.

    shipmmg's wake is w_P0 exp(-4 beta_P^2), and it forms U and beta from v - x_G r; with
    x_G = 0 the second departure vanishes and both codes must agree to rounding.
    """
    return published.replace(x_G=0.0, wake_model='exponential')


def reference_params(p: MmgParams):
    """Return shipmmg's two parameter objects for ``p`` (dimensional where it wants)."""
    unit, m = p.half_rho_l2d, p.mass
    basic = shipmmg.Mmg3DofBasicParams(
        L_pp=p.L_pp, B=p.B, d=p.d, x_G=p.x_G, D_p=p.D_p, m=m, I_zG=m * (p.k_zz * p.L_pp) ** 2,
        A_R=p.A_R, η=p.D_p / p.H_R, m_x=p.m_x * unit, m_y=p.m_y * unit,
        J_z=p.J_z * unit * p.L_pp ** 2, f_α=p.f_alpha, ϵ=p.epsilon, t_R=p.t_R,
        x_R=p.x_R * p.L_pp, a_H=p.a_H, x_H=p.x_H * p.L_pp, γ_R_minus=p.gamma_R_minus,
        γ_R_plus=p.gamma_R_plus, l_R=p.l_R, κ=p.kappa, t_P=p.t_P, w_P0=p.w_P0, x_P=p.x_P)
    names = HULL_X + HULL_Y + HULL_N
    manoeuvring = shipmmg.Mmg3DofManeuveringParams(
        k_0=p.k_0, k_1=p.k_1, k_2=p.k_2,
        **{n + '_dash': getattr(p, n) for n in names})
    return basic, manoeuvring


def random_states(n=64, seed=0):
    rng = np.random.default_rng(seed)
    z = np.c_[rng.uniform(0.4, 1.5, n), rng.uniform(-0.25, 0.25, n), rng.uniform(-0.07, 0.07, n)]
    c = np.c_[rng.uniform(8.0, 20.0, n) * 2 * math.pi, rng.uniform(-0.6, 0.6, n)]
    return z, c


def test_forces_equal_shipmmg(as_shipmmg):
    z, c = random_states()
    basic, man = reference_params(as_shipmmg)
    x_h, x_r, x_p, y_h, y_r, n_h, n_r = (np.asarray(a) for a in
                                         shipmmg.get_sub_values_from_simulation_result(
                                             z[:, 0], z[:, 1], z[:, 2], c[:, 1],
                                             c[:, 0] / (2 * math.pi), basic, man,
                                             ρ=as_shipmmg.rho))
    hull = mmg.hull(z, c, as_shipmmg)
    prop = mmg.propeller(z, c, as_shipmmg)
    rud = mmg.rudder(z, c, as_shipmmg)
    for ours, theirs in ((hull[:, 0], x_h), (hull[:, 1], y_h), (hull[:, 2], n_h),
                         (prop[:, 0], x_p), (rud[:, 0], x_r), (rud[:, 2], n_r)):
        np.testing.assert_allclose(ours, theirs, rtol=1e-8, atol=1e-9)
    # shipmmg's force helper writes Y_R = -(1 - t_R) F_N cos(delta); its equations of
    # motion (and the paper) use -(1 + a_H) F_N cos(delta), which we follow.
    p = as_shipmmg
    np.testing.assert_allclose(rud[:, 1], y_r * (1 + p.a_H) / (1 - p.t_R), rtol=1e-9)
    assert np.all(prop[:, 1:] == 0)


def run_zigzag(p, angles_deg=(10.0,), seconds=60.0, dt=0.05, substeps=2):
    """Closed-loop zig-zags of our model at Yasukawa & Yoshimura's approach condition."""
    angles = np.radians(angles_deg)
    ones = np.ones(len(angles))
    return zigzag(physics(p), SERVICE_SPEED * ones, REV_PER_S * 2 * math.pi * ones, angles, angles,
                  math.radians(15.8), seconds, dt, substeps)


def test_zigzag_equals_shipmmg(as_shipmmg):
    run = run_zigzag(as_shipmmg)
    t, states, rudder, heading = run.t, run.z[0], run.delta[0], run.heading[0]
    basic, man = reference_params(as_shipmmg)
    sol = shipmmg.simulate_mmg_3dof(basic, man, t, rudder, np.full(t.size, REV_PER_S),
                                    u0=SERVICE_SPEED, ρ=as_shipmmg.rho, rtol=1e-9, atol=1e-11)
    ref = sol.sol(t)
    assert heading.max() > math.radians(10.0) and heading.min() < -math.radians(10.0)
    for i in range(3):
        scale = np.abs(states[:, i]).max()
        assert np.abs(ref[i] - states[:, i]).max() < 0.01 * scale
    assert abs(np.degrees(ref[5].max() - heading.max())) < 0.05   # first overshoot, deg


def test_zigzags_run_as_a_batch_and_report_their_overshoots(published):
    both = run_zigzag(published, (10.0, 20.0), seconds=80.0, dt=0.1, substeps=1)
    alone = run_zigzag(published, (20.0,), seconds=80.0, dt=0.1, substeps=1)
    np.testing.assert_allclose(both.z[1], alone.z[0], rtol=1e-12)
    overshoots = both.overshoots()
    assert overshoots.shape == (2, 2) and np.all(overshoots > 0)
    assert overshoots[1, 0] > overshoots[0, 0]    # a larger check angle overshoots more
    # The first is the heading's largest excursion beyond the check angle (IMO) before
    # it swings back past the check angle on the other side.
    back = int(np.flatnonzero(both.heading[0] < -math.radians(10.0))[0])
    assert np.degrees(both.heading[0, :back].max()) - 10.0 == pytest.approx(overshoots[0, 0])


def test_non_dimensional_units(published):
    p = published
    unit = 0.5 * p.rho * p.L_pp ** 2 * p.d
    m = p.rho * p.displacement
    matrix = np.array(p.mass_matrix)
    assert matrix[0, 0] == pytest.approx(m + 0.022 * unit)
    assert matrix[1, 1] == pytest.approx(m + 0.223 * unit)
    assert matrix[1, 2] == matrix[2, 1] == pytest.approx(p.x_G * m)
    izz = m * (0.25 * 7.0) ** 2 + p.x_G ** 2 * m + 0.011 * unit * 7.0 ** 2
    assert matrix[2, 2] == pytest.approx(izz)
    # Straight ahead: X_H = -R_0' rho/2 L d U^2; pure yaw at speed: N_H = N_r' rho/2 L^2 d U r L.
    u, r = 1.2, 0.03
    straight = mmg.hull(np.array([u, 0.0, 0.0]), np.zeros(2), p)
    assert straight[0] == pytest.approx(-0.022 * 0.5 * p.rho * 7.0 * p.d * u * u)
    yaw = mmg.hull(np.array([u, 0.0, r]), np.zeros(2), p)
    r_dash = r * 7.0 / u
    n_expected = 0.5 * p.rho * 49.0 * p.d * u * u * (-0.049 * r_dash - 0.013 * r_dash ** 3)
    assert yaw[2] == pytest.approx(n_expected)
    inverse = inverse_mass_matrix_t(p).T
    np.testing.assert_allclose(inverse @ matrix, np.eye(3), atol=1e-12)


def test_rudder_turns_to_starboard_and_thrust_balances(published):
    z = np.array([SERVICE_SPEED, 0.0, 0.0])
    n = REV_PER_S * 2 * math.pi
    port, stbd = (physics(published).derivative(z, np.array([n, d])) for d in (-0.3, 0.3))
    assert stbd[2] > 0 > port[2]          # positive delta: bow to starboard (MMG)
    ahead = physics(published).derivative(z, np.array([n, 0.0]))
    assert abs(ahead[0]) < 0.05           # m/s^2: near self-propulsion at 17.95 rps


def test_regular_at_rest_with_autograd(published):
    z = torch.zeros(2, 3, dtype=torch.float64, requires_grad=True)
    c = torch.tensor([[0.0, 0.2], [60.0, -0.2]], dtype=torch.float64)
    acc = physics(published).derivative(z, c)
    acc.sum().backward()
    assert torch.isfinite(acc).all() and torch.isfinite(z.grad).all()
    assert acc[0].abs().max() < 1e-6      # at rest, propeller stopped: no force
    assert acc[1, 0] > 0                  # bollard pull
    biased = published.replace(Y_0=10.0, N_0=-5.0)
    np.testing.assert_allclose(physics(biased).force(np.zeros(3), np.zeros(2)), [0.0, 10.0, -5.0],
                               atol=1e-9)


def test_bad_files_refused(tmp_path, published):
    text = PUBLISHED.read_text()
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text.replace('wake_model: yasukawa2015', 'wake_model: kijima'))
    with pytest.raises(ConfigError, match='wake_model'):
        load_physics(bad)
    bad.write_text(text.replace('t_P: 0.220', 't_P: 1.2'))
    with pytest.raises(ConfigError, match='t_P'):
        load_physics(bad)
    bad.write_text(text.replace('X_vv: -0.040', 'Xvv: -0.040'))
    with pytest.raises(ConfigError, match="unknown MMG parameter 'Xvv'"):
        load_physics(bad)
    assert load_physics(PUBLISHED).family is FAMILY
    assert load_physics(config_dir() / 'patrol_vessel.yaml').family is not FAMILY
