"""
The multirotor's reference trajectories: smooth, at rest at the start, the drawn kinds.

Velocity and acceleration must be the derivatives of the position (a tracking
controller feeds the acceleration forward), continuous across the segments' joints;
every kind starts at rest at the start point; run i flies the scenario's i-th kind in
turn, the same whichever batch it is in.
"""

import numpy as np
import pytest

from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.trajectories import (
    KINDS,
    Segment,
    Trajectories,
    smoothstep,
    sweep_phase,
)

FLIGHT = load_simulation({'vessel': 'crazyflie_brushless'}).flight
H = 1e-5     # s, central differences


def trajectories(kinds=KINDS, seed=0, first=0):
    cfg = FLIGHT.__class__(**{**FLIGHT.__dict__, 'kinds': tuple(kinds)})
    rngs = [np.random.default_rng([seed, first + k]) for k in range(len(kinds))]
    return Trajectories(rngs, cfg, range(first, first + len(kinds)), np.full(len(kinds), 0.4))


@pytest.mark.parametrize('kind', KINDS)
def test_velocity_and_acceleration_are_the_derivatives_of_the_position(kind):
    ref = trajectories([kind])
    times = np.linspace(0.05, 40.0, 400)
    for t in times:
        ahead, here, back = ref.at(t + H), ref.at(t), ref.at(t - H)
        np.testing.assert_allclose((ahead.position - back.position) / (2 * H), here.velocity,
                                   atol=2e-6, err_msg=f'{kind} at {t}')
        np.testing.assert_allclose((ahead.velocity - back.velocity) / (2 * H),
                                   here.acceleration, atol=2e-4, err_msg=f'{kind} at {t}')
        assert abs((ahead.yaw - back.yaw)[0] / (2 * H) - here.yaw_rate[0]) < 1e-6


@pytest.mark.parametrize('kind', KINDS)
def test_every_kind_starts_at_rest_at_the_start_and_keeps_its_acceleration_continuous(kind):
    ref = trajectories([kind])
    before, start = ref.at(-1.0), ref.at(1e-9)
    for r in (before, start):
        assert np.abs(r.position).max() < 1e-9 and np.abs(r.velocity).max() < 1e-6
        assert np.abs(r.acceleration).max() < 1e-3
        assert r.yaw[0] == pytest.approx(0.4, abs=1e-9)
    # A continuous acceleration changes half as much in half the time; a step does not.
    samples = np.array([ref.at(t).acceleration[0] for t in np.arange(0.0005, 20.0, 0.0005)])
    fine = np.abs(np.diff(samples, axis=0)).max()
    coarse = np.abs(samples[2:] - samples[:-2]).max()
    assert fine < 0.6 * coarse and coarse < 1.0           # m/s^2 in 1 ms
    positions = np.array([ref.at(t).position[0] for t in np.arange(0.0, 60.0, 0.1)])
    assert 0.3 < np.abs(positions).max() < 2.5            # it flies about, near the start


def test_kinds_follow_the_run_index_whatever_the_batch():
    cycle = ('random', 'square', 'melon')
    cfg = FLIGHT.__class__(**{**FLIGHT.__dict__, 'kinds': cycle})
    rngs = [np.random.default_rng([1, k]) for k in range(5, 9)]
    batch = Trajectories(rngs, cfg, range(5, 9), np.zeros(4))
    assert batch.kinds == ('melon', 'random', 'square', 'melon')
    alone = Trajectories([np.random.default_rng([1, 7])], cfg, [7], np.zeros(1))
    for t in (0.5, 7.0, 31.0):
        np.testing.assert_array_equal(alone.at(t).position[0], batch.at(t).position[2])
    assert batch.describe(1)['kind'] == 'random'


def test_the_square_visits_its_corners_and_changes_layer_after_a_lap():
    ref = trajectories(['square'])
    path = ref.paths[0]
    samples = np.array([ref.at(t).position[0] for t in np.arange(0.0, 40.0, 0.02)])
    corners = np.array(path.corners)
    horizontal = np.linalg.norm(samples[:, None, :2] - corners[None, :, :2], axis=2)
    assert np.all(horizontal.min(axis=0) < 1e-9)          # each corner is reached
    heights = np.unique(np.round(samples[:, 2], 6))
    assert heights.min() < -0.4                           # a layer up (z down)
    np.testing.assert_allclose(np.linalg.norm(corners[1] - corners[0]), path.side)


def test_segments_and_ramps_meet_their_ends():
    seg = Segment(1.0, 2.0, np.zeros(3), np.array([1.0, -2.0, 0.5]), np.array([0.3, 0, 0]),
                  np.array([0, 0.4, 0]))
    p0, v0, a0 = seg.at(1.0)
    p1, v1, a1 = seg.at(3.0)
    np.testing.assert_allclose([p0, v0, a0], [np.zeros(3), [0.3, 0, 0], np.zeros(3)],
                               atol=1e-15)
    np.testing.assert_allclose([p1, v1, a1], [[1.0, -2.0, 0.5], [0, 0.4, 0], np.zeros(3)],
                               atol=1e-14)
    hop = Segment(0.0, 1.0, np.zeros(3), np.ones(3), np.zeros(3), np.zeros(3), 'cycloid')
    assert np.abs(hop.at(0.25)[2]).max() == pytest.approx(2 * np.pi)   # 2 pi D / T^2
    assert smoothstep(0.0, 2.0) == (0.0, 0.0, 0.0) and smoothstep(2.0, 2.0) == (1.0, 0.0, 0.0)
    phase, frequency, _ = sweep_phase(10.0, 0.1, 0.5, 10.0)
    assert frequency == pytest.approx(2 * np.pi * 0.5)    # f_hi after one sweep
