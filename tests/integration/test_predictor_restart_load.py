"""
The predictor behind a simulator killed and restarted, and under a service soak (#14).

Both start their own processes (a module of their own, so no other predictor shares
the graph while they measure).
"""

import os
import signal

import pytest

from .conftest import Graph, wait_for

pytestmark = pytest.mark.ros

START = 5000.0         # the simulator's start time (s)
WINDOW_S = 60.0        # the patrol boat's window


@pytest.mark.slow  # about 30 s: two real-time processes and two 60 s windows
def test_a_simulator_restarted_after_kill_9_is_forecast_again_within_one_window(launcher):
    graph = Graph('hardening_restart', state_topic='/vessel/odom')
    sim_args = ('--ros-args', '-p', 'seed:=3', '-p', f'start_time:={START}',
                '-p', 'real_time_factor:=20.0')
    try:
        sim = launcher.start_node('ship_sim_node', 'simulator', *sim_args)
        predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                        '-p', 'use_sim_time:=true',
                                        '-p', 'diagnostics_period:=0.5')
        assert wait_for(lambda: len(graph.forecasts) >= 3, 120), predictor.output()[-3000:]
        # The node runs on /clock: the input age is measured on it (not the wall clock).
        ages = [float(kv.value) for _, d in graph.diagnostics[-3:] for kv in d.status[0].values
                if kv.key == 'input_age_s' and kv.value != 'n/a']
        assert ages and all(0.0 <= a <= 5.0 for a in ages), ages
        old_end = graph.stamp()
        os.killpg(sim.popen.pid, signal.SIGKILL)
        killed_at, states_at_kill = len(graph.forecasts), len(graph.state_stamps)
        sim.popen.wait(10)
        # The new run at 5x: a wall-clock latency of the restart (the predictor hears the
        # new simulator's topics a moment after this test does) costs 5x its time, not 20x.
        launcher.start_node('ship_sim_node', 'simulator', *sim_args[:-1],
                            'real_time_factor:=5.0', name='simulator2')
        assert wait_for(lambda: graph.stamp() < old_end, 90), predictor.output()[-3000:]
        # Forecasting resumed as soon as the new run had filled one window: judged by the
        # first forecast of the new run (at 20x real time more follow while this polls),
        # from the new run's first state heard here: the messages a simulator sends
        # before the graph has discovered it are lost to every subscriber (a second of
        # discovery on a busy machine was 20 s of a run at 20x).
        first = next(k for k in range(killed_at, len(graph.forecasts))
                     if graph.stamp(k) < old_end)
        heard = next(t for t in graph.state_stamps[states_at_kill:] if t < old_end)
        assert heard >= START, heard
        assert graph.stamp(first) - heard <= WINDOW_S + 10.0, (heard, graph.stamp(first))
        assert graph.count('clock_resets') + graph.count('source_restarts') >= 1
        assert predictor.alive()
    finally:
        graph.close()


@pytest.mark.slow  # about 35 s each: start-up, a 15 s soak of 32 requests in flight
@pytest.mark.parametrize('client', ['c', 'python'])
def test_a_service_soak_answers_every_request_while_forecasts_flow(tmp_path, client):
    from offline.benchmarks.soak import RequestShape, soak

    # 10x real time fills the window in 6 s; a forecast period of 10 s of simulated
    # time is then one a wall second, as on a vessel with the default 1 s.
    result = soak(duration=15.0, clients=4, concurrency=8, shape=RequestShape(plans=64),
                  rtf=10.0, forecast_period=10.0, log_dir=tmp_path, client=client)
    assert result['client'] == client
    assert result['requests_sent'] > 0 and result['requests_success'] > 0, result
    assert result['requests_unanswered'] == 0, result
    assert result['requests_answered'] == result['requests_sent'], result
    assert result['requests_failed_other'] == 0, result
    assert result['predictor_alive'], result
    assert result['longest_silence_periods'] <= 2.0, result
    assert result['forecasts_published'] >= 0.5 * result['duration_s'], result
    # The node's own counts agree with the clients', and refusals were taken unread.
    counts = result['predictor_service_counts']
    assert counts['service_requests'] == result['requests_sent'], counts
    assert counts['service_busy'] == result['requests_busy'], counts
    assert 0 < counts['service_busy_unread'] <= counts['service_busy'], counts
