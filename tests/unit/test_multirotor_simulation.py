"""
The simulator for a 6-DOF vehicle: the Crazyflie flown by its tracking controller.

Against rotorpy 3.0.0 (test-only, requirements/reference.txt): the rotor speed commands
of an aggressive flight of ours, replayed from the same state in rotorpy's
``Multirotor.step`` (aero on, motor lag), give the same positions, velocities, attitudes
and rotor speeds; the differences are RK4's and shrink 16-fold when its step halves.
The simulator: the start at rest at hover, determinism per run, the sample's keys,
sensor noise on the third components, a force hook's steady offset as the controller's
gains say; the controller's allocation inverts the family's forces.
"""

import importlib
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vessel_physics.errors import ConfigError
from vessel_physics.multirotor import forces
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.flight import allocation_matrix, rotation_body_to_ned
from vessel_physics.simulation.simulator import Simulator

VEHICLE = 'crazyflie_brushless'
QUIET = {'vessel': VEHICLE, 'noise': {'enabled': False}}
ROTORS = ('m1', 'm2', 'm3', 'm4')
# Frames as tests/unit/test_multirotor.py: FRD <-> FLU, NED <-> ENU; rotorpy's rotor k is
# our rotor TO_ROTORPY[k] (it lists r1 front left; we m1 front right).
FLU = np.diag([1.0, -1.0, -1.0])
ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
TO_ROTORPY = [3, 0, 1, 2]
# An aggressive flight (seed 0, run 3) whose first 3 s reach 55 degrees of tilt, 7.5 rad/s
# and 2.1 m/s.
SEED, RUN, SECONDS = 0, 3, 3.0


def config(**changes):
    return load_simulation({**QUIET, **changes})


def hover_speed(params):
    return math.sqrt(params.m * params.g / (4 * params.k_eta))


# ------------------------------------------------------------------ against rotorpy
def fly(dt, seconds=SECONDS):
    """Return the true states (every 0.01 s) and the rotor commands of our flight."""
    sim = Simulator(config(dt=dt, flight={'kinds': ['aggressive']}), seed=SEED,
                    run_offset=RUN)
    states, commands = [sim.state], []
    for _ in range(int(round(seconds * 100))):
        sim.advance()
        commands.append([sim.command[m][0] for m in ROTORS])
        states.append(sim.state)
    return states, np.array(commands)


def rotorpy_state(s):
    """Our true state (arrays of one run) in rotorpy's frames (world ENU, body FLU)."""
    r_ned = Rotation.from_euler('ZYX', [s['psi'][0], s['theta'][0], s['phi'][0]]).as_matrix()
    return {'x': ENU @ np.array([s['x'][0], s['y'][0], s['z'][0]]),
            'v': ENU @ r_ned @ np.array([s['u'][0], s['v'][0], s['w'][0]]),
            'q': Rotation.from_matrix(ENU @ r_ned @ FLU).as_quat(),
            'w': FLU @ np.array([s['p'][0], s['q'][0], s['r'][0]]), 'wind': np.zeros(3),
            'rotor_speeds': np.array([s[m][0] for m in ROTORS])[TO_ROTORPY]}


def replay(states, commands, order=TO_ROTORPY, **integrator):
    """Return the largest differences of rotorpy's replay from our states."""
    module = pytest.importorskip('rotorpy.vehicles.multirotor',
                                 reason='rotorpy (requirements/reference.txt) is the reference')
    params = importlib.import_module('rotorpy.vehicles.crazyfliebrushless_params')
    vehicle = module.Multirotor(params.quad_params, aero=True,
                                integrator_kwargs=integrator or None)
    state = rotorpy_state(states[0])
    worst = np.zeros(5)
    for k, command in enumerate(commands):
        state = vehicle.step(state, {'cmd_motor_speeds': command[order]}, 0.01)
        ours = rotorpy_state(states[k + 1])
        angle = (Rotation.from_quat(state['q']).inv() * Rotation.from_quat(ours['q'])).magnitude()
        worst = np.maximum(worst, [np.linalg.norm(state['x'] - ours['x']),
                                   np.linalg.norm(state['v'] - ours['v']), angle,
                                   np.linalg.norm(state['w'] - ours['w']),
                                   np.abs(state['rotor_speeds'] - ours['rotor_speeds']).max()])
    return worst      # position m, velocity m/s, attitude rad, body rates rad/s, rotors rad/s


# rotorpy integrates with scipy's DOP853 at rtol = atol = 1e-12 (its own RK45 default,
# rtol 1e-3, agrees within 3e-7 m too): the reference is exact to far below RK4's error.
EXACT = {'method': 'DOP853', 'rtol': 1e-12, 'atol': 1e-12}


@pytest.fixture(scope='module')
def flight():
    return fly(0.002)


def test_an_aggressive_flight_replayed_in_rotorpy_is_the_same_flight(flight):
    states, commands = flight
    tilt = max(math.degrees(math.acos(math.cos(s['phi'][0]) * math.cos(s['theta'][0])))
               for s in states)
    rate = max(math.hypot(s['p'][0], s['q'][0], s['r'][0]) for s in states)
    assert tilt > 50 and rate > 6.0          # aggressive: the whole envelope is exercised
    assert commands.min() < 0.7 * hover_speed(config().params) < 1.3 * hover_speed(
        config().params) < commands.max()
    dx, dv, angle, dw, rotors = replay(states, commands, **EXACT)
    print(f'RK4 at 2 ms vs rotorpy over {SECONDS:g} s: position {dx:.1e} m, velocity '
          f'{dv:.1e} m/s, attitude {angle:.1e} rad, rates {dw:.1e} rad/s, rotors {rotors:.1e}')
    # RK4's global error at 2 ms (7e-7 m, 1.2e-6 m/s, 2e-7 rad, 4e-7 rad/s, 1.5e-5 rad/s
    # on the rotors here: the next test shows it is RK4's), with a margin of ten.
    assert dx < 1e-5 and dv < 1e-5 and angle < 1e-5 and dw < 1e-5 and rotors < 1e-3


def test_the_difference_is_rk4s_and_shrinks_as_its_step_does(flight):
    states, commands = flight                     # its first 1.5 s: tilts to 55 degrees
    coarse = replay(states[:151], commands[:150], **EXACT)
    fine = replay(*fly(0.001, 1.5), **EXACT)
    print('halving the step divides the differences by', np.round(coarse / fine, 1))
    assert np.all(coarse / fine > 8.0)       # fourth order: 16


def test_commands_sent_to_the_wrong_rotors_make_another_flight(flight):
    """The comparison can fail: rotorpy's own numbering flies off at once."""
    dx, _, angle, _, _ = replay(*flight, order=[0, 1, 2, 3], **EXACT)
    assert dx > 0.05 and angle > 0.5


# ------------------------------------------------------------------ the simulator
def test_a_multirotor_starts_at_rest_at_hover_and_holds_it():
    sim = Simulator(config(flight={'enabled': False}), n_runs=3, seed=2)
    s = sim.sample()
    keys = ('t', 'u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta', 'psi', 'x', 'y', 'z', *ROTORS)
    assert tuple(s)[:len(keys)] == keys
    assert tuple(s)[len(keys):] == tuple(k + '_true' for k in keys[1:13])
    np.testing.assert_allclose([s[k] for k in ROTORS], hover_speed(sim.config.params),
                               rtol=1e-9)
    assert len(set(np.round(s['psi'], 6))) == 3                  # random headings
    out = sim.run(2.0)
    for key in ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta', 'x', 'y', 'z'):
        assert np.abs(out[key + '_true']).max() < 1e-9, key
    assert np.abs(out['psi_true'] - out['psi_true'][:, :1]).max() < 1e-12


def test_batch_run_k_is_the_single_run_k_and_reset_repeats_it():
    cfg = config(warmup_s=0.2)
    batch = Simulator(cfg, n_runs=2, seed=5, run_offset=4).run(1.0)
    single = Simulator(cfg, n_runs=1, seed=5, run_offset=5)
    alone = single.run(1.0)
    for key in batch:
        np.testing.assert_allclose(alone[key][0], batch[key][1], rtol=1e-12, atol=1e-12,
                                   err_msg=key)
    assert np.abs(alone['x_true']).max() > 0.01                   # it flew
    single.reset()
    np.testing.assert_array_equal(single.run(1.0)['z_true'], alone['z_true'])


def test_the_controller_sees_the_truth_so_noise_does_not_change_the_flight():
    noisy = Simulator(load_simulation({'vessel': VEHICLE, 'warmup_s': 0.2}), seed=1).run(1.0)
    quiet = Simulator(config(warmup_s=0.2), seed=1).run(1.0)
    for key in ('x', 'z', 'theta', 'r'):
        np.testing.assert_array_equal(noisy[key + '_true'], quiet[key + '_true'])
    std = load_simulation({'vessel': VEHICLE}).noise.std
    assert std['z'] == 0.001 and std['theta'] == 0.005 and std['m1'] == 5.0
    for key in ('w', 'q', 'theta', 'z'):
        error = (noisy[key] - noisy[key + '_true']).std()
        assert 0.7 * std[key] < error < 1.3 * std[key], key
    rotor = (noisy['m1'] - quiet['m1']).std()
    assert 0.7 * std['m1'] < rotor < 1.3 * std['m1']


def test_the_controller_tracks_each_kind_of_trajectory():
    kinds = ['square', 'random', 'multisine', 'melon', 'aggressive']
    sim = Simulator(config(flight={'kinds': kinds}), n_runs=5, seed=3)
    errors, moved = [], []
    for _ in range(500):
        sim.advance()
        ref, s = sim.operator.last, sim.state
        position = np.stack([s['x'], s['y'], s['z']], axis=-1)
        errors.append(np.linalg.norm(position - ref.position, axis=1))
        moved.append(np.linalg.norm(ref.position, axis=1))
    errors, moved = np.array(errors), np.array(moved)
    assert sim.operator.kinds == tuple(kinds)
    print('median tracking error (m) by kind', dict(zip(kinds, np.median(errors, 0).round(3),
                                                        strict=True)))
    assert np.all(moved.max(axis=0) > 0.3)                        # every kind goes places
    assert np.all(np.median(errors[:, :4], axis=0) < 0.12)       # m (the real: 0.05-0.1)
    assert np.all(errors[:, :4].max(axis=0) < 0.6)
    # The aggressive mix asks for more than 63 degrees of tilt at times: it lags more.
    assert np.median(errors[:, 4]) < 0.3 and errors[:, 4].max() < 1.5


def test_a_force_hook_pushes_the_hover_off_by_force_over_gain(tmp_path, monkeypatch):
    (tmp_path / 'push_hook.py').write_text(
        'import numpy as np\n'
        'def push(t, state, controls, environment):\n'
        '    out = np.zeros((len(state["u"]), 6))\n'
        '    out[:, 0] = 0.02   # N along body x\n'
        '    return out\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    cfg = config(flight={'enabled': False}, extra_forces='push_hook:push', dt=0.005)
    sim = Simulator(cfg, n_runs=1, seed=4)
    psi = sim.state['psi'][0]
    sim.run(4.0)                                  # the position loop settles in 2 s
    s = sim.state
    offset = np.array([s['x'][0], s['y'][0]])
    expected = 0.02 / (cfg.params.m * cfg.flight.controller.position_gain[0])   # PD: F / (m kp)
    assert np.linalg.norm(offset) == pytest.approx(expected, rel=0.03)
    np.testing.assert_allclose(offset / np.linalg.norm(offset), [math.cos(psi), math.sin(psi)],
                               atol=0.02)
    assert s['theta'][0] == pytest.approx(math.atan(0.02 / (cfg.params.m * cfg.params.g)),
                                          rel=0.05)              # leans back against it


def test_the_allocation_inverts_the_familys_thrust_and_torque():
    cfg = config()
    sim = Simulator(cfg, seed=0)
    wrench = np.array([[0.5, 2e-3, -1e-3, 4e-4], [0.3, -1e-3, 5e-4, -2e-4]])
    speeds = sim.operator.rotor_speeds(wrench)
    z = np.zeros((2, 8))
    tau = forces.rotor_thrust(z, speeds, cfg.params) + forces.rotor_torque(z, speeds, cfg.params)
    np.testing.assert_allclose(tau[:, 2:], np.column_stack([-wrench[:, 0], wrench[:, 1:]]),
                               rtol=1e-9, atol=1e-15)
    assert allocation_matrix(cfg.params).shape == (4, 4)
    r = rotation_body_to_ned(np.array([0.3]), np.array([-0.2]), np.array([1.1]))[0]
    np.testing.assert_allclose(r, Rotation.from_euler('ZYX', [1.1, -0.2, 0.3]).as_matrix(),
                               atol=1e-15)


@pytest.mark.parametrize('change, words', [
    ({'wind': {'enabled': True}}, ['wind.enabled', 'feels no wind']),
    ({'current': {'enabled': True}}, ['current.enabled', 'feels no current']),
    ({'flight': {'kinds': ['melon', 'loop']}}, ['flight.kinds', 'square, random']),
    ({'flight': {'controller': {'position_gain': [1, 2]}}},
     ['flight.controller.position_gain', 'a list of 3 numbers']),
    ({'flight': {'melon': {'radius': [1, 2]}}},
     ['flight.melon.radius', "did you mean 'radius_m'"]),
])
def test_bad_flight_scenarios_are_refused_in_one_line(change, words):
    with pytest.raises(ConfigError) as info:
        load_simulation({'vessel': VEHICLE, **change})
    message = str(info.value)
    assert '\n' not in message and all(w in message for w in words), message


def test_a_ship_has_no_flight_section_and_a_drone_no_operator_in_its_manifest():
    with pytest.raises(ConfigError, match='flies vehicles with rotors.*otter'):
        load_simulation({'vessel': 'otter', 'flight': {'enabled': False}})
    assert load_simulation({'vessel': 'otter'}).flight is None
    drone = load_simulation({'vessel': VEHICLE}).to_dict()
    assert 'flight' in drone and 'operator' not in drone
    assert drone['flight']['kinds'] == ['random', 'square', 'multisine', 'random', 'melon',
                                        'aggressive']
