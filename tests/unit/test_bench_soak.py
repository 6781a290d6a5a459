"""The soak's figures when its clients run in processes of their own (offline/benchmarks/soak)."""

import argparse

import pytest

from offline.benchmarks.soak import Merged, positive_int, stage_figures


def raw(sent, success, busy, failed=0, failures=None, stages=()):
    latencies = [0.5] * success + [0.01] * busy + [0.02] * failed
    return {'sent': sent, 'success': success, 'busy': busy, 'failed': failed,
            'failures': failures or {}, 'latencies': latencies,
            'success_latencies': [0.5] * success, 'busy_latencies': [0.01] * busy,
            'busy_stages': [list(s) for s in stages], 'request_kb': 145.4,
            'success_answer_kb': 1652.3 if success else None}


def test_processes_figures_add_up_as_one_clients_would():
    merged = Merged([raw(10, 2, 7, 1, {'no forecast': 1}), raw(5, 0, 4, 1, {'no forecast': 1}),
                     raw(3, 1, 2)])
    assert (merged.sent, merged.success, merged.busy, merged.failed) == (18, 3, 13, 2)
    assert merged.answered == 18
    assert merged.failures == {'no forecast': 2}
    assert len(merged.latencies) == 18 and len(merged.busy_latencies) == 13
    # A process that had no success still lets another's answer give the size.
    assert merged.success_answer_kb == 1652.3 and merged.request_kb == 145.4


def test_busy_stages_of_every_process_are_judged_together():
    fast = [(0, 1_000_000, 1_500_000, 2_000_000, 2_100_000, 3_000_000)] * 99
    slow = [(0, 90_000_000, 91_000_000, 92_000_000, 92_100_000, 93_000_000)]
    figures = stage_figures(Merged([raw(99, 0, 99, stages=fast),
                                    raw(1, 0, 1, stages=slow)]).busy_stages)
    node = figures['to the node and through it']
    assert node['p50'] == 1.0
    assert node['mean_in_slowest_1_percent'] == 90.0   # the slow one, from the other process


@pytest.mark.parametrize('text', ['0', '-2', 'two', '1.5'])
def test_a_count_below_one_is_refused_in_one_line(text):
    with pytest.raises(argparse.ArgumentTypeError, match='integer >= 1'):
        positive_int(text)


@pytest.mark.parametrize(('steps', 'period', 'rows'), [(900, 10.0, 90), (100, 0.0, 100)])
def test_every_plan_covers_the_steps_asked(steps, period, rows):
    from offline.benchmarks.soak import RequestShape, make_request

    request = make_request(RequestShape(plans=3, plan_period=period, answer_period=0.0,
                                        steps=steps))
    assert len(request.plans) == 3
    for plan in request.plans:
        assert len(plan.values) == rows * len(plan.control_names)


def test_latency_percentiles_are_in_ms_and_absent_without_requests():
    from offline.benchmarks.soak import percentile_ms

    assert percentile_ms([0.010, 0.020, 0.030], 50) == 20.0
    assert percentile_ms([0.0101] * 99 + [0.5], 99) == 15.0   # interpolated, as numpy does
    assert percentile_ms([], 99) is None
