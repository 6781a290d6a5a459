"""hybrid_predictor.held_wind: a held wind stays put over the earth while the bow turns."""


import numpy as np
import pytest

from hybrid_models.engine import Forecaster
from hybrid_models.metrics import dead_reckoning, trajectory_errors
from hybrid_predictor.held_wind import forecast_holding_wind, holds_wind, holds_wind_each
from hybrid_predictor.node import default_model_path
from vessel_description import load_vessel
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.operator import Operator
from vessel_physics.simulation.simulator import Simulator

BOAT = load_vessel('patrol_boat')
COS, SIN = BOAT.control_index('wind_dir_cos'), BOAT.control_index('wind_dir_sin')


def test_which_plans_hold_the_wind():
    rows = np.full((5, BOAT.n_control), np.nan)
    rows[:, :3] = 1.0
    assert holds_wind(BOAT, None) and holds_wind(BOAT, rows)
    rows[:, 3:] = [2.0, 1.0, 0.0]
    assert not holds_wind(BOAT, rows)
    assert not holds_wind(load_vessel('kvlcc2_hsva'), None)   # no wind among its controls
    # A request's plans at once, as each alone.
    held = rows.copy()
    held[:, 3:] = np.nan
    assert holds_wind_each(BOAT, np.stack([rows, held, rows])).tolist() == [False, True, False]
    kvlcc2 = load_vessel('kvlcc2_hsva')
    assert not holds_wind_each(kvlcc2, np.full((2, 5, kvlcc2.n_control), np.nan)).any()


@pytest.fixture(scope='module')
def engine():
    return Forecaster.from_checkpoint(default_model_path())


def test_plans_with_their_own_wind_are_forecast_as_given(engine):
    z = np.tile([8.0, 0.0, 0.0, 0.01, 0.0], (engine.window, 1))
    c = np.tile([80.0, 0.1, 0.1, 6.0, 1.0, 0.0], (engine.window, 1))
    future = np.tile(c[-1], (2, 120, 1))
    forecast, used = forecast_holding_wind(engine, z, c, future, [False, True])
    np.testing.assert_array_equal(used[0], future[0])
    # The held plan's wind turned against the heading its own forecast reaches, step by
    # step in the one pass (a positive rudder turns the bow to port, psi falls: the wind
    # from ahead veers to starboard, its angle from the bow positive; docs/conventions.md).
    _, heading = dead_reckoning(forecast.hybrid[1], BOAT)
    np.testing.assert_allclose(np.arctan2(used[1, 1:, SIN], used[1, 1:, COS]),
                               -heading[:-1], atol=1e-5)
    assert used[1, 0, COS] == 1.0 and heading[-1] < -0.5
    # Held at the bow, the same plan forecasts another turn: the held wind acted.
    bow = engine.forecast(z, c, future[1:]).hybrid[0]
    assert np.abs(bow - forecast.hybrid[1]).max() > 1e-3
    with pytest.raises(ValueError, match=r'one flag per plan \(2\)'):
        engine.forecast(z, c, future, hold_wind=[True])
    # Alone or in a batch of two: another compiled float32 program, equal to ~1e-7.
    np.testing.assert_allclose(forecast.hybrid[0], engine.forecast(z, c, future[:1]).hybrid[0],
                               rtol=1e-5, atol=1e-6)


@pytest.mark.slow   # four 15-minute runs simulated and forecast (16-19 s); the rules above
def test_holding_the_wind_over_the_earth_forecasts_turns_better(engine):
    # The demo's scenario (simulator seed 11, operator plans 1011 + k), 4 runs of 15
    # minutes, 10-minute forecasts every 60 s: the error against the noise-free truth
    # with the wind held over the earth is below the one with it held at the bow.
    cfg, runs, seconds, horizon = load_simulation(), 4, 900, 600
    plans = []
    for k in range(runs):
        operator = Operator([np.random.default_rng(1011 + k)], cfg.operator, cfg.vessel)
        plans.append([np.concatenate(operator.setpoints(float(t))) for t in range(seconds)])
    plans = np.array(plans)
    sim = Simulator(cfg, n_runs=runs, seed=11)
    rows = [sim.sample()] + [sim.advance(dict(zip(BOAT.actuator_names, plans[:, t].T,
                                                  strict=True))) for t in range(seconds)]
    data = {k: np.stack([r[k] for r in rows], axis=1) for k in rows[0]}
    z = np.stack([data[s] for s in BOAT.state_names], -1)
    truth = np.stack([data[s + '_true'] for s in BOAT.state_names], -1)
    c = np.stack([data[s] for s in BOAT.control_names], -1)
    errors = {'bow': [], 'earth': []}
    for k in range(runs):
        for te in range(engine.window, seconds - horizon, 60):
            window = (z[k, te - engine.window + 1:te + 1], c[k, te - engine.window + 1:te + 1])
            future = np.tile(c[k, te], (1, horizon, 1))
            future[0, :, :3] = plans[k, te:te + horizon]
            true = truth[k, te + 1:te + 1 + horizon][None]
            bow = engine.forecast(*window, future).hybrid
            earth = forecast_holding_wind(engine, *window, future, [True])[0].hybrid
            errors['bow'].append(trajectory_errors(bow, true, BOAT).mean())
            errors['earth'].append(trajectory_errors(earth, true, BOAT).mean())
    bow, earth = np.mean(errors['bow']), np.mean(errors['earth'])
    assert earth < 0.95 * bow, (bow, earth)
