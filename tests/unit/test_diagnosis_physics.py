"""Candidate terms and physics files: signs, numpy = torch, load/save, the simulator."""

import math

import numpy as np
import pytest
import torch

from vessel_physics.errors import ConfigError
from vessel_physics.family import ExtraTerm, Physics
from vessel_physics.patrol import FAMILY, SIMULATOR_TERMS, candidates
from vessel_physics.patrol.forces import propulsion, wind
from vessel_physics.physics_file import (
    load_physics,
    physics_from_dict,
    write_parameters,
    write_physics,
)
from vessel_physics.simulation.config import load_simulation as load_config
from vessel_physics.simulation.simulator import Simulator

P = load_physics('patrol_vessel').params
CANDIDATES = sorted(n for n, t in FAMILY.terms.items() if t.kind == 'candidate')
RNG = np.random.default_rng(3)
Z = np.column_stack([RNG.uniform(2, 9, 8), RNG.normal(0, 0.3, 8), RNG.normal(0, 0.02, 8),
                     RNG.normal(0, 0.02, 8), RNG.normal(0, 0.03, 8)])
GAMMA = RNG.uniform(-math.pi, math.pi, 8)
C = np.column_stack([RNG.uniform(40, 100, 8), RNG.normal(0, 0.1, 8), RNG.normal(0, 0.1, 8),
                     RNG.uniform(0, 15, 8), np.cos(GAMMA), np.sin(GAMMA)])


@pytest.mark.parametrize('name', CANDIDATES)
def test_candidate_terms_agree_on_numpy_and_torch(name):
    fn = FAMILY.terms[name].fn
    expected = fn(Z, C, P)
    zt = torch.tensor(Z, dtype=torch.float64, requires_grad=True)
    got = fn(zt, torch.tensor(C, dtype=torch.float64), P)
    np.testing.assert_allclose(got.detach().numpy(), expected, rtol=1e-10, atol=1e-9)
    assert expected.shape == (8, 4) and np.isfinite(expected).all()
    if got.requires_grad:   # constant forces (biases) do not depend on the state
        got.sum().backward()
        assert torch.isfinite(zt.grad).all()


def test_wind_from_starboard_pushes_to_port_and_heels_to_port():
    z = np.array([[0.0, 0.0, 0.0, 0.0, 0.0]])
    beam = np.array([[0.0, 0.0, 0.0, 10.0, 0.0, 1.0]])   # 10 m/s from starboard
    assert candidates.relative_wind_sway(z, beam, P)[0, 1] < 0
    assert candidates.relative_wind_roll(z, beam, P)[0, 2] < 0
    assert np.sign(candidates.relative_wind_sway(z, beam, P)[0, 1]) == np.sign(
        wind(z, beam, P)[0, 1])
    head = np.array([[0.0, 0.0, 0.0, 10.0, 1.0, 0.0]])
    q = 0.5 * 1.224 * 100.0
    assert candidates.relative_wind_surge(z, head, P)[0, 0] == pytest.approx(-q)


def test_rudder_offset_is_the_derivative_of_propulsion():
    b = 1e-3   # a wider central difference than the term's own
    up, down = C.copy(), C.copy()
    up[:, 1:3] += b
    down[:, 1:3] -= b
    numeric = (propulsion(Z, up, P) - propulsion(Z, down, P)) / (2 * b)
    np.testing.assert_allclose(candidates.rudder_offset(Z, C, P), numeric, rtol=1e-5,
                               atol=1e-2)


def test_propeller_asymmetry_turns_the_bow_to_port_when_port_pushes_harder():
    straight = np.array([[80.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
    tau = candidates.propeller_asymmetry(np.array([[6.0, 0, 0, 0, 0]]), straight, P)[0]
    assert tau[0] == pytest.approx(0.0) and tau[1] == pytest.approx(0.0)
    assert tau[3] > 0   # more port thrust: yaw to starboard (N > 0, FRD)


def test_plain_vessel_file_means_every_simulator_term():
    physics = load_physics('patrol_vessel.yaml')
    assert physics.terms == SIMULATOR_TERMS and physics.params == P
    assert not physics.extra_terms


def test_physics_file_round_trip(tmp_path):
    extra = (ExtraTerm('relative_wind_sway', 'Y', 212.0, {'category': 'wind'}),
             ExtraTerm('propulsion', 'XYKN', -0.05))
    physics = Physics(FAMILY, FAMILY.replace(P, Xauu=-2400.0), (
        'rigid_body_coriolis', 'restoring', 'hull_damping', 'propulsion'), extra)
    write_parameters(physics, tmp_path / 'v.yaml', 'header\nline')
    write_physics(physics, tmp_path / 'p.yaml', 'v.yaml', 'a physics')
    loaded = load_physics(tmp_path / 'p.yaml')
    assert loaded.params == physics.params and loaded.terms == physics.terms
    assert [t.to_dict() for t in loaded.extra_terms] == [t.to_dict() for t in extra]
    np.testing.assert_allclose(loaded.force(Z, C), physics.force(Z, C), rtol=1e-12)
    manual = Physics(FAMILY, physics.params, physics.terms).force(Z, C)
    manual[:, 1] += 212.0 * candidates.relative_wind_sway(Z, C, P)[:, 1]
    manual -= 0.05 * propulsion(Z, C, P)
    np.testing.assert_allclose(loaded.force(Z, C), manual, rtol=1e-12)


@pytest.mark.parametrize('data, message', [
    ({'format': 'vessel-physics/1', 'vessel': 'patrol_vessel.yaml', 'terms': ['wnd']},
     "terms: unknown term 'wnd' (did you mean 'wind'?)"),
    ({'format': 'vessel-physics/1', 'vessel': 'patrol_vessel.yaml',
      'extra_terms': [{'term': 'sway_linear', 'dofs': 'Q', 'coefficient': 1.0}]},
     'extra_terms[0]: dofs: expected letters of XYKN'),
    ({'format': 'vessel-physics/1', 'vesel': 'x'}, "unknown key 'vesel' (did you mean"),
    ({'format': 'vessel-physics/2', 'family': 'mmg', 'parameters': 'patrol_vessel.yaml'},
     'not a parameter file of the MMG standard model'),
    ({'format': 'vessel-physics/2', 'family': 'fossen', 'parameters': 'otter_fossen.yaml',
      'extra_terms': [{'term': 'roll_bias', 'dofs': 'K', 'coefficient': 1.0}]},
     "unknown term 'roll_bias'"),
    ({'format': 'vessel-physics/2', 'family': 'raft'}, 'family: expected one of patrol, mmg'),
    ({'format': 'wavefront/1'}, "format: 'wavefront/1' is no physics or parameter file"),
])
def test_bad_physics_files_fail_with_one_line(data, message):
    with pytest.raises(ConfigError, match=None) as info:
        physics_from_dict(data, source='p.yaml')
    assert message in str(info.value) and '\n' not in str(info.value)


def test_simulator_adds_the_extra_terms_of_its_physics(tmp_path):
    physics = Physics(FAMILY, P, SIMULATOR_TERMS, (ExtraTerm('sway_bias', 'Y', 20000.0),))
    write_physics(physics, tmp_path / 'p.yaml', 'patrol_vessel.yaml')
    quiet = {'waves': {'enabled': False}, 'wind': {'enabled': False},
             'noise': {'enabled': False}, 'operator': {'enabled': False}, 'warmup_s': 0.0}
    pushed = Simulator(load_config({**quiet, 'physics': str(tmp_path / 'p.yaml')}),
                       seed=1).run(60)
    plain = Simulator(load_config(quiet), seed=1).run(60)
    assert pushed['v_true'][0, -1] > plain['v_true'][0, -1] + 0.05   # pushed to starboard
