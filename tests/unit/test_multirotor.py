"""
The multirotor family and the Crazyflie 2.1 Brushless: closed forms, by hand, and rotorpy.

Closed forms: hover is an equilibrium, free fall accelerates at g, a yaw rate at hover
stays (MinQ) or decays by rotor drag as k_d n d^2 says, gravity's components, the
attitude rates. By hand: thrust, its moments and the yaw torque of given rotor speeds.
Against rotorpy 3.0.0 (test-only, requirements/reference.txt): the whole derivative of
the shipped file and of a perturbed craft (products of inertia, parasitic drag, hubs off
the CG's plane) on 50 random states, in rotorpy's frames (world z up, body FLU), within
1e-9; the same with the spin senses swapped must fail, which proves them.
"""

import copy
import importlib
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
import torch
import yaml

from vessel_description import load_vessel, parse_vessel
from vessel_description.vocabulary import STATE_MIRROR
from vessel_physics.errors import ConfigError
from vessel_physics.families import FAMILIES
from vessel_physics.files import config_dir
from vessel_physics.integrator import free_run
from vessel_physics.multirotor import FAMILY, MINQ_TERMS, forces
from vessel_physics.physics_file import load_physics

FILE = config_dir() / 'crazyflie_brushless_multirotor.yaml'
VESSEL = load_vessel('crazyflie_brushless')
PHYSICS = load_physics(FILE).for_vessel(VESSEL)
P = PHYSICS.params
HOVER = math.sqrt(P.m * P.g / (4 * P.k_eta))     # rad/s on each rotor
# Frames: FRD <-> FLU (a rotation by pi about x) and NED <-> ENU.
FLU = np.diag([1.0, -1.0, -1.0])
ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
# rotorpy lists r1 front-left, r2 front-right, r3 rear-right, r4 rear-left; the file
# lists the Crazyflie's m1 front right, m2 rear right, m3 rear left, m4 front left.
TO_ROTORPY = [3, 0, 1, 2]      # rotorpy's rotor k is our rotor TO_ROTORPY[k]


def minq(physics=PHYSICS):
    """Return the physics restricted to the MinQ terms."""
    return physics.replace(terms=FAMILY.term_sets['minq'])


def state(u=0.0, v=0.0, w=0.0, p=0.0, q=0.0, r=0.0, phi=0.0, theta=0.0):
    return np.array([[u, v, w, p, q, r, phi, theta]])


def random_flight(n=50, seed=0):
    """States (n, 8), headings (n,) and rotor speeds (n, 4) across the flight envelope."""
    rng = np.random.default_rng(seed)
    z = np.column_stack([rng.uniform(-3.0, 3.0, (n, 3)), rng.uniform(-8.0, 8.0, (n, 3)),
                         rng.uniform(-1.2, 1.2, (n, 2))])
    return z, rng.uniform(-math.pi, math.pi, n), rng.uniform(0.0, 3100.0, (n, 4))


# ------------------------------------------------------------------ closed forms
def test_hover_level_at_rest_is_an_equilibrium():
    c = np.full((1, 4), HOVER)
    np.testing.assert_allclose(PHYSICS.derivative(state(), c), 0.0, atol=1e-12)
    assert 1600.0 < HOVER < 1650.0     # rad/s: inside the motors' 0-3100


def test_free_fall_and_the_components_of_gravity():
    stopped = np.zeros((1, 4))
    np.testing.assert_allclose(PHYSICS.derivative(state(), stopped)[0],
                               [0, 0, P.g, 0, 0, 0, 0, 0], atol=1e-15)
    phi, theta = 0.4, -0.3
    expected = P.g * np.array([-math.sin(theta), math.cos(theta) * math.sin(phi),
                               math.cos(theta) * math.cos(phi)])
    acc = PHYSICS.derivative(state(phi=phi, theta=theta), stopped)[0]
    np.testing.assert_allclose(acc[:3], expected, rtol=1e-14)
    np.testing.assert_allclose(acc[3:], 0.0, atol=1e-15)
    np.testing.assert_allclose(forces.gravity(state(phi=phi, theta=theta), None, P)[0, :3],
                               P.m * expected, rtol=1e-14)


def test_a_yaw_rate_at_hover_stays_in_minq_and_rotor_drag_damps_it():
    r0, c = 2.0, np.full((1, 4), HOVER)
    run = free_run(minq().derivative, state(r=r0), np.tile(c, (1, 100, 1)), 0.01)[0]
    np.testing.assert_allclose(run[:, 5], r0, rtol=1e-13)
    np.testing.assert_allclose(np.delete(run, 5, axis=1), 0.0, atol=1e-12)
    # The full model: each hub moves at r0 d across its rotor's axis (d its distance from
    # the axis of yaw): the H-force k_d n r0 d against it, the lift k_h (r0 d)^2 up.
    d2 = P.rotors[0].x ** 2 + P.rotors[0].y ** 2
    acc = PHYSICS.derivative(state(r=r0), c)[0]
    assert acc[5] == pytest.approx(-4 * P.k_d * HOVER * r0 * d2 / P.Izz, rel=1e-12)
    assert acc[2] == pytest.approx(-4 * P.k_h * r0 ** 2 * d2 / P.m, rel=1e-9)
    np.testing.assert_allclose(acc[[0, 1, 3, 4, 6, 7]], 0.0, atol=1e-12)


def test_kinematic_rates_are_the_euler_zyx_rates():
    rng = np.random.default_rng(3)
    z = np.column_stack([np.zeros((20, 3)), rng.uniform(-3, 3, (20, 3)),
                         rng.uniform(-1.2, 1.2, (20, 2))])
    p, q, r, phi, theta = z[:, 3:].T
    turn = q * np.sin(phi) + r * np.cos(phi)
    expected = np.column_stack([p + turn * np.tan(theta), q * np.cos(phi) - r * np.sin(phi)])
    np.testing.assert_allclose(FAMILY.kinematic_rates(z), expected, rtol=1e-13)


def test_mass_matrix_holds_the_inertia_tensor():
    params = FAMILY.replace(P, Ixy=1e-6, Ixz=-2e-6, Iyz=3e-6)
    m = FAMILY.mass_matrix(params)
    np.testing.assert_allclose(m[:3, :3], P.m * np.eye(3))
    np.testing.assert_allclose(m[3:, 3:], [[P.Ixx, 1e-6, -2e-6], [1e-6, P.Iyy, 3e-6],
                                           [-2e-6, 3e-6, P.Izz]])
    assert not m[:3, 3:].any() and not m[3:, :3].any()


def test_the_vehicle_files_mirror_image_is_the_physics_mirror_image():
    # The Crazyflie is symmetric about its x-z plane: its vessel file swaps m1 and m4, m2
    # and m3 (opposite spins); mirrored states and rotor speeds give mirrored rates.
    sign = np.array([STATE_MIRROR[s] for s in VESSEL.state_names])
    swap = [VESSEL.control_index(VESSEL.mirror[a]) for a in VESSEL.actuator_names]
    z, _, c = random_flight(20, seed=4)
    np.testing.assert_allclose(PHYSICS.derivative(z * sign, c[:, swap]),
                               PHYSICS.derivative(z, c) * sign, rtol=1e-12, atol=1e-9)


# ------------------------------------------------------------------ by hand
def test_rotor_thrust_moments_and_yaw_torque_by_hand():
    n = np.array([[1000.0, 1500.0, 2000.0, 2500.0]])     # m1 FR, m2 RR, m3 RL, m4 FL
    t = P.k_eta * n[0] ** 2
    a = P.rotors[0].x
    thrust = forces.rotor_thrust(state(), n, P)[0]
    np.testing.assert_allclose(thrust, [0.0, 0.0, -t.sum(),
                                        # starboard rotors lift the starboard side: K < 0
                                        -a * (t[0] + t[1] - t[2] - t[3]),
                                        # front rotors lift the nose: M > 0
                                        a * (t[0] - t[1] - t[2] + t[3]), 0.0], rtol=1e-14)
    # m1 and m3 spin ccw: their reaction yaws the body clockwise seen from above, +N.
    yaw = forces.rotor_torque(state(), n, P)[0]
    q = P.k_m * n[0] ** 2
    np.testing.assert_allclose(yaw, [0, 0, 0, 0, 0, q[0] - q[1] + q[2] - q[3]], rtol=1e-14)
    assert [r.spin for r in P.rotors] == ['ccw', 'cw', 'ccw', 'cw']


def test_rotor_drag_lift_and_parasitic_drag_by_hand():
    params = FAMILY.replace(P, c_Dx=1e-3, c_Dy=2e-3, c_Dz=3e-3)
    n = np.array([[1000.0, 1200.0, 1400.0, 1600.0]])
    u, v, w = 1.0, -2.0, 0.5
    drag = forces.rotor_drag(state(u, v, w), n, params)[0]
    total = n.sum()
    a = P.rotors[0].x
    # In pure translation every hub sees (u, v, w); hubs in the CG's plane: the moments
    # are x Hy - y Hx about z only, and of Hz about x and y.
    hz = -P.k_z * w * n[0]
    np.testing.assert_allclose(drag[:3], [-P.k_d * u * total, -P.k_d * v * total,
                                          -P.k_z * w * total], rtol=1e-14)
    xs, ys = np.array([a, -a, -a, a]), np.array([a, a, -a, -a])
    hx, hy = -P.k_d * u * n[0], -P.k_d * v * n[0]
    np.testing.assert_allclose(drag[3:], [(ys * hz).sum(), -(xs * hz).sum(),
                                          (xs * hy - ys * hx).sum()], rtol=1e-12, atol=1e-18)
    lift = forces.translational_lift(state(u, v, w), n, P)[0]
    np.testing.assert_allclose(lift, [0, 0, -4 * P.k_h * (u * u + v * v), 0, 0, 0],
                               atol=1e-18)
    speed = math.sqrt(u * u + v * v + w * w)
    np.testing.assert_allclose(forces.parasitic_drag(state(u, v, w), n, params)[0],
                               [-speed * 1e-3 * u, -speed * 2e-3 * v, -speed * 3e-3 * w, 0, 0,
                                0], rtol=1e-14)


def test_candidates_by_hand():
    z, n = state(phi=0.3, theta=-0.2), np.array([[1000.0, 1500.0, 2000.0, 2500.0]])
    shares = sum(FAMILY.terms[f'rotor{i}_thrust'].fn(z, n, P) for i in range(1, 5))
    np.testing.assert_allclose(shares, forces.rotor_thrust(z, n, P)
                               + forces.rotor_torque(z, n, P), rtol=1e-14)
    one = FAMILY.terms['rotor1_thrust'].fn(z, n, P)[0]
    t = P.k_eta * 1000.0 ** 2
    np.testing.assert_allclose(one, [0, 0, -t, -P.rotors[0].y * t, P.rotors[0].x * t,
                                     P.k_m * 1000.0 ** 2], rtol=1e-14)
    assert not FAMILY.terms['rotor5_thrust'].fn(z, n, P).any()    # a quadrotor has four
    weight, (phi, theta) = P.m * P.g, (0.3, -0.2)
    np.testing.assert_allclose(FAMILY.terms['cg_offset_x'].fn(z, n, P)[0],
                               [0, 0, 0, 0, -weight * math.cos(theta) * math.cos(phi),
                                weight * math.cos(theta) * math.sin(phi)], rtol=1e-14)
    np.testing.assert_allclose(FAMILY.terms['cg_offset_y'].fn(z, n, P)[0],
                               [0, 0, 0, weight * math.cos(theta) * math.cos(phi), 0,
                                weight * math.sin(theta)], rtol=1e-14)
    for i, name in enumerate(('surge_bias', 'sway_bias', 'heave_bias', 'roll_bias',
                              'pitch_bias', 'yaw_bias')):
        np.testing.assert_array_equal(FAMILY.terms[name].fn(z, n, P)[0], np.eye(6)[i])


# ------------------------------------------------------------------ against rotorpy
@pytest.fixture(scope='module')
def rotorpy():
    """Return rotorpy's Multirotor class and its Crazyflie Brushless parameters."""
    module = pytest.importorskip('rotorpy.vehicles.multirotor',
                                 reason='rotorpy (requirements/reference.txt) is the reference')
    params = importlib.import_module('rotorpy.vehicles.crazyfliebrushless_params')
    return module.Multirotor, params.quad_params


def rotorpy_rates(vehicle, z, psi, speeds):
    """
    Return rotorpy's (inertial acceleration ENU, body angular acceleration FLU, q, q').

    ``z`` and ``psi`` our state and heading, ``speeds`` the rotor speeds in rotorpy's
    order; the world frame is ENU, the body FLU, R = ENU R_ned(psi, theta, phi) FLU.
    """
    r_ned = Rotation.from_euler('ZYX', [psi, z[7], z[6]]).as_matrix()
    quat = Rotation.from_matrix(ENU @ r_ned @ FLU).as_quat()       # [x, y, z, w]
    s = vehicle._pack_state({'x': np.zeros(3), 'v': ENU @ r_ned @ z[:3], 'q': quat,
                             'w': FLU @ z[3:6], 'wind': np.zeros(3), 'rotor_speeds': speeds})
    s_dot = vehicle._s_dot_fn(0.0, s, speeds)
    return s_dot[3:6], s_dot[10:13], quat, s_dot[6:10]


def compare(physics, vehicle, n=50, seed=0):
    """Return (ours, rotorpy's) accelerations: inertial (ENU) and angular (FLU), (n, 6)."""
    z, psi, c = random_flight(n, seed)
    rates = physics.derivative(z, c)
    ours, theirs = np.empty((n, 6)), np.empty((n, 6))
    for k in range(n):
        r_ned = Rotation.from_euler('ZYX', [psi[k], z[k, 7], z[k, 6]]).as_matrix()
        # a = R (v_b' + w x v_b): the body-frame derivative plus the frame's rotation.
        accel = ENU @ r_ned @ (rates[k, :3] + np.cross(z[k, 3:6], z[k, :3]))
        ours[k] = np.r_[accel, FLU @ rates[k, 3:6]]
        a, w_dot, _, _ = rotorpy_rates(vehicle, z[k], psi[k], c[k, TO_ROTORPY])
        theirs[k] = np.r_[a, w_dot]
    return ours, theirs


def assert_equal_to_rotorpy(ours, theirs):
    scale = np.abs(theirs).max(axis=0)
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-9 * scale.max())


@pytest.mark.parametrize('aero', [True, False], ids=['model', 'minq'])
def test_equal_to_rotorpy_crazyflie_brushless(rotorpy, aero):
    multirotor, quad_params = rotorpy
    physics = PHYSICS if aero else minq()
    ours, theirs = compare(physics, multirotor(quad_params, aero=aero))
    assert_equal_to_rotorpy(ours, theirs)
    assert np.abs(theirs[:, 3:]).max() > 100.0      # rad/s^2: the moments are exercised


def test_equal_to_rotorpy_with_products_of_inertia_drag_and_hubs_off_plane(rotorpy):
    multirotor, quad_params = rotorpy
    theirs = copy.deepcopy(quad_params)
    # rotorpy's body frame is FLU: positions (x, -y, -z), Ixy and Ixz change sign.
    flu = {'r1': (0.050, 0.040, 0.010), 'r2': (0.045, -0.043, 0.012),
           'r3': (-0.040, -0.050, 0.008), 'r4': (-0.047, 0.041, 0.011)}
    theirs.update(Ixy=2e-6, Ixz=-1.5e-6, Iyz=1e-6, c_Dx=5e-4, c_Dy=6e-4, c_Dz=9e-4,
                  rotor_pos={k: np.array(v) for k, v in flu.items()})
    data = FAMILY.parameter_values(P)
    data.update(Ixy=-2e-6, Ixz=1.5e-6, Iyz=1e-6, c_Dx=5e-4, c_Dy=6e-4, c_Dz=9e-4,
                rotors=[{**rotor, **dict(zip('xyz', map(float, FLU @ flu[f'r{k}']), strict=True))}
                        for rotor, k in zip(data['rotors'], (2, 3, 4, 1), strict=True)])
    params = FAMILY.read_parameters(data, 'perturbed')
    assert params.rotors[0].z == -0.012 and params.rotors[3].y == -0.040
    ours, reference = compare(PHYSICS.replace(params=params), multirotor(theirs, aero=True),
                              seed=1)
    assert_equal_to_rotorpy(ours, reference)


def test_swapped_spins_or_mirrored_rotors_disagree_with_rotorpy(rotorpy):
    """The comparison can fail: it fixes the spin senses and the rotors' positions."""
    multirotor, quad_params = rotorpy
    vehicle = multirotor(quad_params, aero=True)
    data = FAMILY.parameter_values(P)
    swapped = [{**r, 'spin': 'cw' if r['spin'] == 'ccw' else 'ccw'} for r in data['rotors']]
    mirrored = [{**r, 'y': -r['y']} for r in data['rotors']]
    for rotors in (swapped, mirrored):
        wrong = FAMILY.read_parameters({**data, 'rotors': rotors}, 'wrong')
        ours, theirs = compare(PHYSICS.replace(params=wrong), vehicle, n=10)
        assert np.abs(ours[:, 3:] - theirs[:, 3:]).max() > 1.0      # rad/s^2


def test_attitude_rates_follow_rotorpy_quaternion(rotorpy):
    multirotor, quad_params = rotorpy
    vehicle = multirotor(quad_params, aero=True)
    z, psi, c = random_flight(20, seed=2)
    rates = FAMILY.kinematic_rates(z)
    h = 1e-7
    for k in range(len(z)):
        _, _, quat, quat_dot = rotorpy_rates(vehicle, z[k], psi[k], c[k, TO_ROTORPY])
        euler = []
        for step in (-h, h):
            moved = quat + step * quat_dot
            r_ned = ENU.T @ Rotation.from_quat(moved / np.linalg.norm(moved)).as_matrix() @ FLU
            euler.append(Rotation.from_matrix(r_ned).as_euler('ZYX'))
        _, theta_rate, phi_rate = (euler[1] - euler[0]) / (2 * h)
        np.testing.assert_allclose(rates[k], [phi_rate, theta_rate], rtol=1e-6, atol=1e-6)


# ------------------------------------------------------------------ arrays, files, vessels
@pytest.mark.parametrize('name', sorted(FAMILY.terms))
def test_numpy_and_torch_agree_and_gradients_flow(name):
    rng = np.random.default_rng(0)
    z = np.column_stack([rng.uniform(-3, 3, (8, 6)), rng.uniform(-1, 1, (8, 2))])
    z[0, :3] = 0.0        # at rest: parasitic drag's |v| must not make NaN gradients
    c = rng.uniform(0, 3100, (8, 4))
    fn = FAMILY.terms[name].fn
    expected = fn(z, c, P)
    zt, ct = torch.tensor(z, requires_grad=True), torch.tensor(c, requires_grad=True)
    got = fn(zt, ct, P)
    np.testing.assert_allclose(got.detach().numpy(), expected, rtol=1e-12, atol=1e-15)
    assert expected.shape == (8, 6)
    if got.requires_grad:
        got.sum().backward()
        grads = [g for g in (zt.grad, ct.grad) if g is not None]
        assert grads and all(torch.isfinite(g).all() for g in grads)


JAX_CHECK = """
import json
import jax
jax.config.update('jax_enable_x64', True)
import jax.numpy as jnp
import numpy as np
from vessel_physics.physics_file import load_physics
physics = load_physics('crazyflie_brushless_multirotor').with_parameters(c_Dx=1e-3, c_Dz=2e-3)
rng = np.random.default_rng(5)
z = np.column_stack([rng.uniform(-3, 3, (16, 6)), rng.uniform(-1, 1, (16, 2))])
c = rng.uniform(0, 3100, (16, 4))
rates = jax.jit(physics.derivative)(jnp.asarray(z), jnp.asarray(c))
grad = jax.grad(lambda zz: physics.derivative(zz, jnp.asarray(c)).sum())(jnp.zeros((16, 8)))
print(json.dumps({'diff': float(np.abs(np.asarray(rates) - physics.derivative(z, c)).max()),
                  'finite': bool(np.isfinite(np.asarray(grad)).all())}))
"""


def test_the_model_compiles_in_jax():
    # A fresh interpreter: double precision is jax's global switch. The gradient is taken
    # at rest, where parasitic drag's |v| must give no NaN.
    env = {k: v for k, v in os.environ.items() if k != 'XLA_FLAGS'}
    env['PYTHONPATH'] = os.pathsep.join(p for p in sys.path if p)   # pytest's pythonpath
    out = subprocess.run([sys.executable, '-c', JAX_CHECK], capture_output=True, text=True,
                         env=env, timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result['diff'] < 1e-10 and result['finite']


def test_the_parameter_file_round_trips_and_names_its_units():
    assert FAMILIES['multirotor'] is FAMILY and PHYSICS.family is FAMILY
    assert FAMILY.read_parameters(FAMILY.parameter_values(P), 'again') == P
    assert FAMILY.term_sets['minq'] == MINQ_TERMS
    assert set(MINQ_TERMS) < set(FAMILY.model_terms)
    assert set(FAMILY.model_terms) == {n for n, t in FAMILY.terms.items() if t.kind == 'force'}
    for name in FAMILY.parameter_names():
        assert FAMILY.parameter_unit(name)
        assert set(FAMILY.parameter_dofs(name)) <= set('XYZKMN')
    # The diagnosis varies a parameter through the terms that read it.
    extra, minv_t = PHYSICS.parameter_variant('k_m', 1e-10)
    z, c = state(), np.array([[1000.0, 1500.0, 2000.0, 2500.0]])
    np.testing.assert_allclose(extra(z, c, None)[0, 5], 1e-10 * (1e6 - 2.25e6 + 4e6 - 6.25e6))
    assert minv_t is None
    assert FAMILY.actuator_dynamics(P, VESSEL) == {f'm{i}': (0.0, 3100.0, 0.05, math.inf)
                                                   for i in range(1, 5)}


@pytest.mark.parametrize('change, message', [
    (lambda d: d.update(k_etta=d.pop('k_eta')), "unknown parameter 'k_etta' \\(did you mean "
                                                "'k_eta'"),
    (lambda d: d.update(m=-0.044), 'm: must be > 0'),
    (lambda d: d.update(k_d=-1e-6), 'k_d: must be >= 0'),
    (lambda d: d.update(Ixy=1e-4), 'positive definite'),
    (lambda d: d['rotors'][1].update(spin='clockwise'), 'spin: expected cw or ccw'),
    (lambda d: d['rotors'][0].update(spinn=d['rotors'][0].pop('spin')),
     "unknown rotor key 'spinn' \\(did you mean 'spin'"),
    (lambda d: d['rotors'][3].update(actuator='m1'), 'each needs its own actuator'),
    (lambda d: d.update(rotors=[]), 'non-empty list'),
])
def test_bad_files_are_refused_in_one_line(tmp_path, change, message):
    data = yaml.safe_load(FILE.read_text())
    change(data)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=message) as info:
        load_physics(path)
    assert '\n' not in str(info.value)


def test_a_vehicle_whose_actuators_do_not_fit_is_refused():
    data = VESSEL.to_dict()
    data.pop('mirror', None)
    data['actuators'][3]['name'] = 'm5'
    with pytest.raises(ConfigError, match="drive a rotor 'm4'"):
        load_physics(FILE).for_vessel(parse_vessel(data))
    data = VESSEL.to_dict()
    data.pop('mirror', None)
    data['actuators'][0]['kind'] = 'propeller'
    with pytest.raises(ConfigError, match="drive a rotor 'm1'"):
        load_physics(FILE).for_vessel(parse_vessel(data))
    data = VESSEL.to_dict()
    data['environment'] = ['wind']
    with pytest.raises(ConfigError, match="environment \\['wind'\\]: the multirotor"):
        load_physics(FILE).for_vessel(parse_vessel(data))
