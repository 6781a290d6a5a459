"""Wind field, waves, current, operator and noise: spectra, signs, determinism."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import integrate

from vessel_physics.simulation.config import load_simulation as load_config
from vessel_physics.simulation.current import CurrentField, draw_current
from vessel_physics.simulation.noise import SensorNoise
from vessel_physics.simulation.operator import RPM, Operator
from vessel_physics.simulation.waves import (
    WaveDraw,
    WaveField,
    draw_waves,
    jonswap,
    mean_peak_period,
)
from vessel_physics.simulation.wind import WindField, draw_wind, harris_spectrum

CFG = load_config({})
P = CFG.physics.family.wave_hull(CFG.params)   # the patrol boat's box hull
RHO_G = 1014.0 * 9.81


def test_jonswap_holds_the_significant_wave_height():
    hs, tp = 2.0, mean_peak_period(2.0)
    m0, _ = integrate.quad(lambda w: jonswap(w, hs, tp), 0.05, 20.0, limit=200)
    assert 4 * math.sqrt(m0) == pytest.approx(hs, rel=0.03)
    assert mean_peak_period(1.0) == pytest.approx(4.883 + 2.68)
    w = np.linspace(0.3, 3, 2000)
    assert w[np.argmax(jonswap(w, hs, tp))] == pytest.approx(2 * math.pi / tp, rel=0.01)


def test_drawn_components_carry_the_spectrum_energy():
    draw = draw_waves(np.random.default_rng(1), CFG.waves)
    m0 = np.sum(draw.amplitude ** 2) / 2
    # The band [0.5, 3.5] w0 holds nearly all of the energy.
    assert 4 * math.sqrt(m0) == pytest.approx(draw.hs, rel=0.05)
    edges = np.linspace(0.5, 3.5, CFG.waves.components + 1) * 2 * math.pi / draw.tp
    assert np.all((draw.omega > edges[:-1]) & (draw.omega < edges[1:]))


def one_component(a=1.0, omega=0.8, chi=0.0):
    draw = WaveDraw(1.0, 8.0, chi, np.array([omega]), np.array([a]), np.array([chi]),
                    np.array([0.0]))
    cfg = SimpleNamespace(force_scale=1.0, gain_surge=1.0, gain_sway=1.0, gain_roll=1.0,
                          gain_yaw=1.0)
    return WaveField([draw], P, cfg)


def froude_krylov_by_quadrature(a, k, beta, theta):
    """-integral of grad p over the box hull, p = rho g a e^-kz cos(theta - k(xi cb + zeta sb))."""
    L, B, T = 51.5, 8.6, 2.3
    xi = np.linspace(-L / 2, L / 2, 401)
    zeta = np.linspace(-B / 2, B / 2, 81)
    zz = np.linspace(0, T, 41)
    X, Z, D = np.meshgrid(xi, zeta, zz, indexing='ij')
    cb, sb = math.cos(beta), math.sin(beta)
    # grad of p: d/dxi = rho g a e^-kz k cb sin(...), d/dzeta likewise with sb.
    s = RHO_G * a * np.exp(-k * D) * k * np.sin(theta - k * (X * cb + Z * sb))
    fx, fy = -s * cb, -s * sb
    n_density = X * fy - Z * fx

    def vol(f):
        return integrate.trapezoid(integrate.trapezoid(integrate.trapezoid(f, zz), zeta), xi)

    return vol(fx), vol(fy), vol(n_density)


@pytest.mark.parametrize('beta_deg, omega', [(30.0, 0.8), (120.0, 1.1), (90.0, 0.6)])
def test_box_froude_krylov_forces_match_quadrature(beta_deg, omega):
    beta = math.radians(beta_deg)
    field = one_component(omega=omega, chi=beta)   # heading 0: beta = chi
    k = omega ** 2 / 9.81
    t = 1.3
    theta = omega * t
    got = field.forces(t, np.zeros(1), np.zeros(1), np.zeros(1))[0]
    fx, fy, n = froude_krylov_by_quadrature(1.0, k, beta, theta)
    scale = RHO_G * 51.5 * 8.6 * (1 - math.exp(-k * 2.3))
    assert got[0] == pytest.approx(fx, abs=2e-3 * scale)
    assert got[1] == pytest.approx(fy, abs=2e-3 * scale)
    assert got[3] == pytest.approx(n, abs=2e-3 * scale * 51.5 / 4)
    # Roll: effective slope, -rho g nabla GM * d(eta)/d(zeta) averaged over hull and draught.
    sl = math.sin(k * 51.5 * math.cos(beta) / 2) / (k * 51.5 * math.cos(beta) / 2) \
        if abs(math.cos(beta)) > 1e-9 else 1.0
    sb = math.sin(k * 8.6 * math.sin(beta) / 2) / (k * 8.6 * math.sin(beta) / 2)
    slope = k * math.sin(beta) * math.sin(theta) * sl * sb * (1 - math.exp(-k * 2.3)) / (k * 2.3)
    assert got[2] == pytest.approx(-RHO_G * 357.0 * 1.1 * slope, rel=1e-5)


def test_wave_force_signs_follow_the_direction():
    # Beam sea from port travelling to starboard: sway force, no surge; head sea: no sway.
    beam = one_component(chi=math.pi / 2)
    head = one_component(chi=math.pi)
    ts = np.linspace(0, 20, 200)
    fb = np.array([beam.forces(t, np.zeros(1), np.zeros(1), np.zeros(1))[0] for t in ts])
    fh = np.array([head.forces(t, np.zeros(1), np.zeros(1), np.zeros(1))[0] for t in ts])
    assert np.abs(fb[:, 0]).max() < 1e-6 * np.abs(fb[:, 1]).max()
    assert np.abs(fh[:, 1]).max() < 1e-6 * np.abs(fh[:, 0]).max()
    assert np.abs(fh[:, 3]).max() < 1e-6 * np.abs(fb[:, 1]).max()


def test_encounter_frequency_from_the_moving_position():
    omega, speed = 0.9, 8.0
    k = omega ** 2 / 9.81
    for chi, expected in ((0.0, omega - k * speed), (math.pi, omega + k * speed)):
        field = one_component(omega=omega, chi=chi)
        h = 1e-3
        phases = [field.phases(t, np.array([speed * t]), np.zeros(1))[0, 0]
                  for t in (10.0, 10.0 + h)]
        rate = math.remainder(phases[1] - phases[0], 2 * math.pi) / h
        assert rate == pytest.approx(expected, rel=1e-6)


def test_shifting_the_origin_keeps_the_sea_in_place():
    draws = [draw_waves(np.random.default_rng(3), CFG.waves)]
    a = WaveField(draws, P, CFG.waves)
    b = WaveField(draws, P, CFG.waves)
    b.shift_origin(np.array([120.0]), np.array([-40.0]))
    np.testing.assert_allclose(b.elevation(5.0, np.array([0.0]), np.array([0.0])),
                               a.elevation(5.0, np.array([120.0]), np.array([-40.0])),
                               atol=1e-9)


def test_harris_gusts_have_the_spectrum_variance():
    cfg = CFG.wind
    draw = draw_wind(np.random.default_rng(2), cfg)
    var_synth = np.sum(draw.gust_amp ** 2) / 2
    lo, hi = cfg.gust_frequency_hz
    var, _ = integrate.quad(lambda f: harris_spectrum(f, draw.mean_speed,
                                                      cfg.gust_drag_coefficient,
                                                      cfg.gust_length_scale_m), lo, hi,
                            limit=200, points=[1e-3, 1e-2, 1e-1])
    assert var_synth == pytest.approx(var, rel=0.3)
    assert 0.05 < math.sqrt(var) / draw.mean_speed < 0.25   # turbulence intensity


def test_wind_field_is_smooth_deterministic_and_nonnegative():
    draws = [draw_wind(np.random.default_rng(s), CFG.wind) for s in range(4)]
    field = WindField(draws)
    t = np.arange(0, 3600, 0.5)
    speeds = np.array([field.at(float(x))[0] for x in t])
    assert np.all(speeds >= 0)
    again = WindField(draws)
    np.testing.assert_array_equal(again.at(123.4)[0], field.at(123.4)[0])
    # Smooth: no jumps between neighbouring half-seconds bigger than a gust allows.
    assert np.abs(np.diff(speeds, axis=0)).max() < 1.0
    directions = np.array([field.at(float(x))[1] for x in t])
    assert np.abs(directions - field.from_ned0).max() < math.radians(4 * CFG.wind.veer_std_deg)


def test_current_components_and_drift():
    cfg = load_config({'current': {'enabled': True, 'speed_mps': [0.5, 0.5],
                                   'variation': 0.0}}).current
    field = CurrentField([draw_current(np.random.default_rng(0), cfg)])
    north, east = field.ned(0.0)
    assert math.hypot(north[0], east[0]) == pytest.approx(0.5)
    psi = np.array([0.7])
    u_c, v_c = field.body(0.0, psi)
    # Body components rotate the NED current by -psi.
    assert u_c[0] == pytest.approx(north[0] * math.cos(0.7) + east[0] * math.sin(0.7))
    assert v_c[0] == pytest.approx(-north[0] * math.sin(0.7) + east[0] * math.cos(0.7))
    off = CurrentField([draw_current(np.random.default_rng(0), load_config({}).current)])
    assert not off.active


def test_operator_orders_are_routine_like_and_per_run_deterministic():
    cfg = CFG.operator
    rngs = [np.random.default_rng(s) for s in range(20)]
    op = Operator(rngs, cfg, CFG.vessel)
    history = []
    for t in range(3600):
        history.append(op.setpoints(float(t)))
    n, dp, ds = (np.array([h[i] for h in history]) for i in range(3))
    assert n.min() >= 366 * RPM - 1e-9 and n.max() <= 980 * RPM + 1e-9
    assert np.abs(dp).max() <= 0.3 + 0.02
    assert np.abs(dp - ds).max() < 0.02
    assert np.mean(np.abs(dp) <= 0.06) > 0.7           # mostly routine small orders
    changes = np.count_nonzero(np.diff(n, axis=0)) / 20
    assert 2 <= changes <= 60                          # shaft holds of minutes
    rudder_changes = np.count_nonzero(np.diff(dp, axis=0)) / 20
    assert 20 <= rudder_changes <= 400                 # rudder holds of tens of seconds
    alone = Operator([np.random.default_rng(7)], cfg, CFG.vessel)
    hist7 = [alone.setpoints(float(t))[0][0] for t in range(3600)]
    np.testing.assert_array_equal(hist7, n[:, 7])


def test_noise_streams_are_per_run():
    cfg = CFG.noise
    batch = SensorNoise([np.random.default_rng(s) for s in range(3)], cfg)
    single = SensorNoise([np.random.default_rng(2)], cfg)
    for _ in range(100):
        np.testing.assert_array_equal(batch.next()[2], single.next()[0])
    sigma = np.array([cfg.std[c] for c in batch.channels])
    draws = np.array([single.next()[0] for _ in range(2000)])
    np.testing.assert_allclose(draws.std(axis=0), sigma, rtol=0.1)
