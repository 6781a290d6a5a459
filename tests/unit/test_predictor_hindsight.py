"""hybrid_predictor.hindsight: the model judged on forecasts re-made with the applied inputs."""

import numpy as np
import pytest

from hybrid_models.metrics import reported_steps
from hybrid_predictor.hindsight import Hindsight, Remade
from hybrid_predictor.skill import LiveSkill, Settings

DT = 1.0
H = 40
STEPS = reported_steps(H)            # 10, 20, 30, 40
SIGMA = 0.05                         # measurement scatter of u (m/s)
Z90, Z50 = 1.645, 0.674              # normal quantiles of the synthetic bands
SETTINGS = Settings(forecast_period=5.0, window=300.0, min_samples=10, warn_coverage=0.5,
                    clear_coverage=0.7, sustain=30.0)


def vessel_speed(n):
    """Return the synthetic vessel's speed (m/s) under shaft order ``n``: its model, exactly."""
    return 0.5 * np.asarray(n, float)


def banded(u: np.ndarray, x0: float) -> Remade:
    """Return a forecast of speeds ``u`` (H,) from x0 along x, with bands of SIGMA."""
    states = np.column_stack([u, np.zeros(len(u))])
    spread = np.array([[Z50 * SIGMA, Z50 * SIGMA], [Z90 * SIGMA, Z90 * SIGMA]])
    radius = np.array([np.full(len(u), 2.0), np.full(len(u), 4.0)])
    return Remade(states, x0 + np.cumsum(u) * DT, np.zeros(len(u)), (0.5, 0.9),
                  states[None] - spread[:, None, :], states[None] + spread[:, None, :],
                  radius)


def remake(window, applied):
    """Return the model's forecast from a window (its last position) under the applied orders."""
    return banded(vessel_speed(applied[:, 0]), window)


def orders(t):
    """Return the order of an operator who changes it every 25 s (10 <-> 14)."""
    return 10.0 if (t // 25) % 2 == 0 else 14.0


def tracker(**changes):
    return LiveSkill(['u', 'r'], STEPS, Settings(**{**SETTINGS.__dict__, **changes}), DT)


def sail(feed, t_to, offset=0.0, skip=(), seed=0):
    """
    Sail under ``orders`` for ``t_to`` s; ``feed(t, u, x, n)`` gets every measurement.

    ``offset`` (m/s) is what the vessel does beyond its model.
    """
    rng = np.random.default_rng(seed)
    x = 0.0
    for t in np.arange(0.0, t_to, DT):
        u = float(vessel_speed(orders(t))) + offset + SIGMA * rng.standard_normal()
        x += u * DT
        if t not in skip:
            feed(t, u, x, orders(t))


def with_hindsight(offset=0.0, t_to=600.0, skip=()):
    hindsight = Hindsight(tracker(), remake)
    raised = []

    def feed(t, u, x, n):
        hindsight.add_measurement(t, [u, 0.0], x, 0.0, [n])
        hindsight.keep(t, x)
        raised.append(hindsight.skill.departure().active)
    sail(feed, t_to, offset, skip)
    return hindsight, raised


def test_a_vessel_true_to_its_model_is_not_judged_departed_under_changing_orders():
    hindsight, raised = with_hindsight()
    assert not any(raised)
    assert hindsight.skill.departure().judged
    assert hindsight.counts['windows_remade'] > 50
    u = hindsight.skill.summary()[40]['u']
    assert u['n'] > 30 and u['rmse'] == pytest.approx(SIGMA, rel=0.4)


def test_the_same_vessel_judged_on_held_orders_would_be_a_false_alarm():
    # What the node did before: the forecasts it published held the latest order.
    skill = tracker()
    raised = []

    def feed(t, u, x, n):
        skill.add_measurement(t, [u, 0.0], x, 0.0)
        skill.add_forecast(t, *vars(banded(np.full(H, float(vessel_speed(n))), x)).values())
        raised.append(skill.departure().active)
    sail(feed, 600.0)
    assert any(raised)


def test_a_vessel_that_departs_from_its_model_is_raised_as_its_first_step_matures():
    hindsight, raised = with_hindsight(offset=0.5)   # ten band widths
    first = raised.index(True)
    # The first scored step's scores of min_samples windows, then sustained: judged as
    # that step matures, not one horizon (H) later.
    judged = STEPS[0] + SETTINGS.min_samples * SETTINGS.forecast_period + SETTINGS.sustain
    assert STEPS[0] + SETTINGS.sustain <= first <= judged + 10
    assert {name for name, _, _ in hindsight.skill.departure().affected} >= {'u'}


def test_each_step_is_given_just_before_the_measurement_that_scores_it():
    seen = []

    class Recorder(LiveSkill):
        def add_measurement(self, t, *args):
            seen.append(('m', t))
            super().add_measurement(t, *args)

        def add_forecast(self, stamp, *args, step=None):
            seen.append(('f', stamp, step))
            return super().add_forecast(stamp, *args, step=step)

    hindsight = Hindsight(Recorder(['u', 'r'], STEPS, SETTINGS, DT), remake)
    sail(lambda t, u, x, n: (hindsight.add_measurement(t, [u, 0.0], x, 0.0, [n]),
                             hindsight.keep(t, x)), 200.0)
    measured = [entry[1] for entry in seen if entry[0] == 'm']
    assert measured == sorted(measured) and measured[-1] == 199.0   # no delay
    for i, entry in enumerate(seen):
        if entry[0] == 'f':
            _, stamp, step = entry
            assert step in STEPS
            following = next(e for e in seen[i + 1:] if e[0] == 'm')
            assert following[1] == stamp + step * DT     # the measurement it is scored by
    stamps = sorted({entry[1] for entry in seen if entry[0] == 'f'})
    assert np.allclose(np.diff(stamps), 5.0)
    # every scored step of every kept window was scored once its time came: none missing
    assert hindsight.skill.counts['steps_missing'] == 0
    matured = [(t, k) for t in stamps for k in STEPS if t + k <= 199.0]
    assert hindsight.skill.counts['steps_scored'] == len(matured) > 0
    assert hindsight.counts['windows_remade'] == len(stamps)   # a window's first step on


def test_the_applied_controls_are_the_measured_ones_at_each_step():
    got = []

    def spy(window, applied):
        got.append((window, applied[:, 0].copy()))
        return remake(window, applied)

    hindsight = Hindsight(tracker(), spy)
    sail(lambda t, u, x, n: (hindsight.add_measurement(t, [u, 0.0], x, 0.0, [n]),
                             hindsight.keep(t, t)), 120.0)
    assert {len(applied) for _, applied in got} == set(STEPS)   # each step's own inputs
    for stamp, applied in got:
        assert np.array_equal(applied, [orders(stamp + k) for k in range(1, len(applied) + 1)])


def test_a_window_whose_inputs_have_a_gap_is_scored_only_before_it():
    got = []

    def spy(window, applied):
        stamp, x = window
        got.append((stamp, len(applied)))
        return remake(x, applied)

    hindsight = Hindsight(tracker(), spy)
    skip = {float(t) for t in range(100, 110)}
    sail(lambda t, u, x, n: (hindsight.add_measurement(t, [u, 0.0], x, 0.0, [n]),
                             hindsight.keep(t, (t, x))), 300.0, skip=skip)
    known = {}
    for stamp, n in got:
        known[stamp] = max(n, known.get(stamp, 0))
    assert known[55.0] == H                       # its horizon ends before the gap
    assert known[60.0] == 30 and known[80.0] == 10   # its scored steps before 100 s
    assert 90.0 not in known and 95.0 not in known   # not even the first scored step
    assert hindsight.counts['windows_gapped'] == 8      # 60, 65, ..., 95
    assert hindsight.skill.counts['steps_missing'] == 0
    assert not hindsight.skill.departure().active


def test_time_going_back_starts_again_and_memory_is_bounded():
    hindsight = Hindsight(tracker(), remake)
    for t in np.arange(0.0, 300.0, DT):
        hindsight.add_measurement(t, [5.0, 0.0], 5.0 * t, 0.0, [10.0])
        hindsight.keep(t, 5.0 * t)
        assert len(hindsight.rows) <= H / DT + 2
        assert len(hindsight.windows) <= H / 5.0 + 2
    assert hindsight.skill.counts['steps_scored'] > 0
    hindsight.add_measurement(3.0, [5.0, 0.0], 15.0, 0.0, [10.0])   # a restarted source
    assert len(hindsight.rows) == 1 and not hindsight.windows
    assert hindsight.skill.summary()[10]['u']['n'] == 0


def test_windows_are_kept_one_per_the_trackers_period_and_a_non_positive_one_is_refused():
    hindsight = Hindsight(tracker(forecast_period=10.0), remake)
    assert sum(hindsight.keep(t, 0.0) for t in np.arange(0.0, 30.0, 1.0)) == 3
    with pytest.raises(ValueError, match='forecast_period'):
        Hindsight(tracker(forecast_period=0.0), remake)
