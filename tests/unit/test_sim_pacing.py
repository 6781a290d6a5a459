"""The simulator node's pacing: late ticks are made up, a hopeless lag is let go."""

import pytest

from ship_sim_node.pacing import Pacer


def run(pacer, ticks, period=0.01):
    """Tick at the given wall times; return the periods simulated at each and sim time."""
    sim_t, done = 0.0, []
    for now in ticks:
        n = pacer.due(now, sim_t)
        sim_t += n * period
        done.append(n)
    return done, sim_t


def test_on_time_ticks_simulate_one_period_each():
    pacer = Pacer(0.01)
    pacer.restart(100.0, 0.0)
    done, sim_t = run(pacer, [100.0 + 0.01 * k for k in range(1, 101)])
    assert done == [1] * 100 and sim_t == pytest.approx(1.0)


def test_a_late_tick_is_made_up_and_an_early_one_waits():
    pacer = Pacer(0.01)
    pacer.restart(0.0, 0.0)
    done, sim_t = run(pacer, [0.01, 0.02, 0.053, 0.06, 0.064, 0.08])
    assert done == [1, 1, 3, 1, 0, 2] and sim_t == pytest.approx(0.08)


def test_faster_than_real_time_owes_more_periods_per_tick():
    pacer = Pacer(0.1)
    pacer.restart(0.0, 0.0, real_time_factor=10.0)
    done, sim_t = run(pacer, [0.01 * k for k in range(1, 11)], period=0.1)
    assert done == [1] * 10 and sim_t == pytest.approx(1.0)


def test_a_hopeless_lag_is_let_go_and_counted():
    pacer = Pacer(0.01, max_catch_up=5)
    pacer.restart(0.0, 0.0)
    done, sim_t = run(pacer, [0.01, 1.01, 1.02, 1.03])
    assert done == [1, 1, 1, 1] and pacer.skipped == 99
    assert sim_t == pytest.approx(0.04)


def test_the_first_tick_owes_one_period_without_a_restart():
    assert Pacer(0.01).due(5.0, 0.0) == 1
