"""Simulator API, determinism, rest and decay, environment signs and the force hook."""

import math
import sys

import numpy as np
import pytest

from vessel_physics.errors import ConfigError
from vessel_physics.patrol.family import mass_matrix
from vessel_physics.simulation.config import load_simulation as load_config
from vessel_physics.simulation.operator import RPM
from vessel_physics.simulation.simulator import Simulator, onset_weight

SAMPLE_KEYS = ('t', 'u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y', 'n', 'delta_port',
               'delta_stbd', 'wind_speed', 'wind_dir_cos', 'wind_dir_sin', 'u_true', 'v_true',
               'p_true', 'r_true', 'phi_true', 'psi_true', 'x_true', 'y_true')

CALM = {'wind': {'enabled': False}, 'waves': {'enabled': False},
        'noise': {'enabled': False}, 'operator': {'enabled': False}, 'warmup_s': 0.0}
STOP = {'n': 0.0, 'delta_port': 0.0, 'delta_stbd': 0.0}


def calm(**extra):
    return load_config({**CALM, **extra})


def at_rest(sim, **state):
    values = dict(u=0, v=0, p=0, r=0, phi=0, psi=0, x=0, y=0, n=0, delta_port=0,
                  delta_stbd=0)
    values.update(state)
    sim.set_state(**values)


def test_sample_has_the_documented_keys_and_starts_at_origin():
    sim = Simulator(load_config({'warmup_s': 10.0}), n_runs=3, seed=5)
    s = sim.sample()
    assert tuple(s) == SAMPLE_KEYS
    assert all(v.shape == (3,) for v in s.values())
    assert np.all(s['t'] == 0) and np.all(s['x_true'] == 0) and np.all(s['y_true'] == 0)
    np.testing.assert_allclose(s['wind_dir_cos'] ** 2 + s['wind_dir_sin'] ** 2, 1.0)
    # Cruise start: the initial speed is the steady speed of the first shaft order.
    assert np.all(s['u_true'] > 2.5) and np.all(np.abs(s['phi_true']) < 0.1)
    assert sim.sample()['u'].tolist() == s['u'].tolist()     # same noise when asked again
    out = sim.run(20)
    assert out['t'].shape == (3, 21)
    np.testing.assert_array_equal(out['t'][0], np.arange(21.0))
    assert np.all(np.diff(out['psi_true'], axis=1) < 1.0)    # unwrapped, smooth


def test_batch_run_k_equals_single_run_with_offset_k():
    cfg = load_config({'warmup_s': 20.0})
    batch = Simulator(cfg, n_runs=3, seed=11).run(120)
    for k in (0, 2):
        single = Simulator(cfg, n_runs=1, seed=11, run_offset=k).run(120)
        for key in SAMPLE_KEYS:
            np.testing.assert_allclose(single[key][0], batch[key][k], rtol=1e-12, atol=1e-12,
                                       err_msg=key)


def test_reset_reproduces_and_new_seed_differs():
    cfg = load_config({'warmup_s': 5.0})
    sim = Simulator(cfg, n_runs=2, seed=3)
    first = sim.run(10)
    sim.reset()
    np.testing.assert_array_equal(sim.run(10)['u'], first['u'])
    sim.reset(seed=4)
    assert sim.seed == 4
    assert not np.allclose(sim.sample()['u'], first['u'][:, 0])


def test_command_overrides_operator_whose_stream_still_advances():
    cfg = load_config({'warmup_s': 0.0, 'operator': {'rudder_hold_s': [5.0, 10.0],
                                                     'shaft_hold_s': [5.0, 10.0]}})
    free = Simulator(cfg, n_runs=2, seed=9)
    driven = Simulator(cfg, n_runs=2, seed=9)
    for _ in range(30):
        free.advance()
        driven.advance({'n': 500 * RPM, 'delta_port': [0.1, -0.1]})
    np.testing.assert_allclose(driven.state['n'], 500 * RPM, rtol=1e-3)
    assert driven.state['delta_port'][0] == pytest.approx(0.1, abs=1e-3)
    np.testing.assert_array_equal(driven.operator.shaft, free.operator.shaft)
    np.testing.assert_array_equal(driven.operator.angle, free.operator.angle)
    with pytest.raises(KeyError, match='unknown command'):
        driven.advance({'rpm': 3.0})
    with pytest.raises(ValueError, match='finite'):
        driven.advance({'n': math.nan})


def test_no_input_no_environment_stays_at_rest():
    sim = Simulator(calm(), n_runs=1)
    at_rest(sim)
    for _ in range(120):
        s = sim.advance(STOP)
    for key in ('u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y'):
        assert s[key + '_true'][0] == 0.0, key


def test_without_forcing_motion_decays():
    sim = Simulator(calm(), n_runs=1)
    at_rest(sim, u=5.0, v=0.5, p=0.05, r=0.02, phi=0.1)
    u = [sim.sample()['u_true'][0]]
    for _ in range(600):
        s = sim.advance(STOP)
        u.append(s['u_true'][0])
    assert np.all(np.diff(u) <= 1e-12)                       # surge decays monotonically
    assert abs(s['u_true'][0]) < 0.5 and abs(s['v_true'][0]) < 0.05
    assert abs(s['r_true'][0]) < 1e-3 and abs(s['phi_true'][0]) < 1e-3
    assert abs(s['p_true'][0]) < 1e-3


def test_beam_wind_from_port_pushes_to_starboard_and_heels_to_starboard():
    cfg = load_config({**CALM, 'wind': {'enabled': True, 'mean_speed_mps': [15.0, 15.0],
                                        'gusts': False, 'veer_std_deg': 0.0}})
    sim = Simulator(cfg, n_runs=1, seed=2)
    # gamma = from - psi = -pi/2: the wind comes from port.
    at_rest(sim, psi=sim.wind.from_ned0[0] + math.pi / 2)
    for _ in range(30):
        s = sim.advance(STOP)
    assert s['wind_dir_sin'][0] < -0.95     # still from port (the wind yaws it a little)
    assert s['v_true'][0] > 0.05            # drifts to starboard
    assert s['phi_true'][0] > 0.002         # heels to starboard (leeward)


def test_positive_rudder_turns_the_bow_to_port():
    sim = Simulator(calm(), n_runs=1)
    at_rest(sim, u=7.0, n=800 * RPM)
    for _ in range(30):
        s = sim.advance({'n': 800 * RPM, 'delta_port': 0.1, 'delta_stbd': 0.1})
    assert s['r_true'][0] < -0.005 and s['psi_true'][0] < -0.05


def test_current_drifts_a_vessel_that_holds_still_in_the_water():
    cfg = calm(current={'enabled': True, 'speed_mps': [0.4, 0.4], 'variation': 0.0})
    sim = Simulator(cfg, n_runs=1, seed=1)
    at_rest(sim)
    for _ in range(100):
        s = sim.advance(STOP)
    north, east = sim.current.ned(0.0)
    assert s['x_true'][0] == pytest.approx(100 * north[0], rel=1e-9, abs=1e-9)
    assert s['y_true'][0] == pytest.approx(100 * east[0], rel=1e-9, abs=1e-9)
    assert math.hypot(s['u_true'][0], s['v_true'][0]) == pytest.approx(0.4)


HOOK_SOURCE = """
import numpy as np
CALLS = []

def push_starboard(t, state, controls, environment):
    CALLS.append((t, sorted(state), sorted(controls), sorted(environment)))
    n = state['u'].shape[0]
    out = np.zeros((n, 4))
    out[:, 1] = 20000.0
    return out

def wrong_shape(t, state, controls, environment):
    return np.zeros(3)
"""


@pytest.fixture()
def hook_module(tmp_path, monkeypatch):
    (tmp_path / 'my_hook_mod.py').write_text(HOOK_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield 'my_hook_mod'
    sys.modules.pop('my_hook_mod', None)


def test_hook_adds_a_constant_force_as_physics_says(hook_module):
    sim = Simulator(calm(extra_forces=f'{hook_module}:push_starboard'), n_runs=2)
    at_rest(sim)
    s = sim.advance(STOP)
    # Starting from rest the acceleration is M^-1 [0, F, 0, 0] (quadratic damping ~ 0).
    expected_v = np.linalg.solve(mass_matrix(sim.config.params), [0, 20000.0, 0, 0])[1] * 1.0
    assert s['v_true'][0] == pytest.approx(expected_v, rel=0.02)
    for _ in range(120):
        s = sim.advance(STOP)
    # It drifts to starboard (east at psi = 0); a force at CO, forward of the centre of
    # lateral resistance, also yaws it a little to starboard.
    assert s['y_true'][0] > 50 and abs(s['x_true'][0]) < 0.15 * s['y_true'][0]
    assert 0 < s['psi_true'][0] < 0.5
    # Sway speed bounded by Yv|v| v|v| + F = 0 at u = 0.
    assert 0.5 < s['v_true'][0] < 1.1 * math.sqrt(20000.0 / 3700.0)
    module = sys.modules[hook_module]
    t, state_keys, control_keys, env_keys = module.CALLS[-1]
    assert state_keys == sorted(['u', 'v', 'u_water', 'v_water', 'p', 'r', 'phi', 'psi', 'x',
                                 'y'])
    assert control_keys == ['delta_port', 'delta_stbd', 'n']
    assert env_keys == ['current_east', 'current_north', 'wave_elevation', 'wind_dir',
                        'wind_speed']


def test_a_hook_switched_on_mid_run_comes_in_smoothly_from_its_time(hook_module):
    sim = Simulator(calm(extra_forces=f'{hook_module}:push_starboard',
                         extra_forces_from_s=5.0, extra_forces_ramp_s=4.0), n_runs=2)
    at_rest(sim)
    v = []
    for _ in range(12):
        v.append(sim.advance(STOP)['v_true'][0])
    assert v[:5] == [0.0] * 5                 # nothing until t = 5 s
    assert 0.0 < v[5] < v[6] < v[7] < v[8]    # then the push sets in
    free = Simulator(calm(extra_forces=f'{hook_module}:push_starboard'), n_runs=2)
    at_rest(free)
    first = free.advance(STOP)['v_true'][0]
    # a second of full push adds what a push from the start gives in its first second
    assert v[10] - v[9] == pytest.approx(first, rel=0.1)


def test_the_onset_is_a_smoothstep():
    assert onset_weight(3.0, None, 60.0) == 1.0
    w = [onset_weight(t, 10.0, 4.0) for t in (9.0, 10.0, 11.0, 12.0, 14.0, 20.0)]
    assert w[0] == w[1] == 0.0 and w[3] == 0.5 and w[4] == w[5] == 1.0
    assert w[2] == pytest.approx(0.15625)     # 3 s^2 - 2 s^3 at s = 1/4: slope 0 at 0


def test_an_onset_without_a_hook_is_refused_in_one_line():
    with pytest.raises(ConfigError, match='extra_forces_from_s: .* extra_forces is null'):
        load_config({'extra_forces_from_s': 100.0})


def test_hook_with_wrong_output_fails_clearly(hook_module):
    sim = Simulator(calm(extra_forces=f'{hook_module}:wrong_shape'), n_runs=2)
    with pytest.raises(ValueError, match=r'must return finite forces of shape \(2, 4\)'):
        sim.advance(STOP)


def test_bad_hook_path_is_one_line():
    with pytest.raises(ConfigError) as info:
        load_config({'extra_forces': 'vessel_physics.nothing_here:f'})
    assert '\n' not in str(info.value) and 'cannot import' in str(info.value)


def test_constructor_validates_arguments():
    with pytest.raises(ValueError, match='n_runs'):
        Simulator(calm(), n_runs=0)
    with pytest.raises(ValueError, match='seed'):
        Simulator(calm(), seed=-1)
    sim = Simulator(calm())
    with pytest.raises(KeyError, match='unknown state'):
        sim.set_state(speed=3.0)


@pytest.mark.slow       # twelve 5-minute runs (12 s); spectrum, forces: test_physics_environment
def test_default_sea_looks_like_the_papers_data():
    # Wave-induced motions (waves on minus waves off, same seeds) of a few runs.
    base = {'noise': {'enabled': False}, 'warmup_s': 30.0}
    on = Simulator(load_config(base), n_runs=6, seed=0).run(300)
    off = Simulator(load_config({**base, 'waves': {'enabled': False}}), n_runs=6,
                    seed=0).run(300)
    std = {k: np.median((on[k + '_true'] - off[k + '_true']).std(axis=1))
           for k in ('u', 'v', 'p', 'r', 'phi')}
    print('median wave-induced std', {k: round(float(v), 4) for k, v in std.items()})
    assert 0.002 < std['p'] < 0.02
    assert 0.002 < std['phi'] < 0.03
    assert 0.0005 < std['r'] < 0.006
    assert 0.01 < std['v'] < 0.15
