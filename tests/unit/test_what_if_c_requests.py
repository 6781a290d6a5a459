"""what_if_c.door: a Predict request read in C into read-only records, as Door.take gives it."""

import re

from builtin_interfaces.msg import Time
import numpy as np
import pytest
from rclpy.serialization import serialize_message
from what_if_c.door import read_request

from hybrid_predictor.plan_message import control_plan
from hybrid_predictor.plans import PlanError, PlanLimits, check_plan_messages
from hybrid_predictor_interfaces.msg import ControlPlan
from hybrid_predictor_interfaces.srv import Predict
from vessel_description import load_vessel

PATROL = load_vessel('patrol_boat')
H = 5


def _plans(rng, count: int, n: float = 80.0) -> list[ControlPlan]:
    rows = lambda: np.column_stack([np.full(H, n), rng.uniform(0, 0.1, (H, 2))])  # noqa
    return [control_plan(PATROL, rows(), plan_id=f'plan {i} ✓',
                         stamp=Time(sec=100 + i, nanosec=250_000_000))
            for i in range(count)]


def test_each_plan_reads_as_its_message():
    rng = np.random.default_rng(0)
    coarse = control_plan(PATROL, np.full((2, 3), 0.05), step_period=3 * PATROL.dt)
    coarse.header.frame_id = 'base_link'
    plans = [*_plans(rng, 3), coarse, ControlPlan()]   # shared, coarse and empty layouts
    request = Predict.Request(plans=plans, answer_period=2.5)
    read = read_request(serialize_message(request))
    assert read.answer_period == 2.5 and len(read.plans) == len(plans)
    for got, want in zip(read.plans, plans, strict=True):
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == (
            want.header.stamp.sec, want.header.stamp.nanosec)
        assert got.header.frame_id == want.header.frame_id and got.plan_id == want.plan_id
        assert list(got.control_names) == want.control_names
        assert list(got.control_units) == want.control_units
        assert list(got.values) == list(want.values) and got.step_period == want.step_period
    with pytest.raises((AttributeError, TypeError)):   # read-only: the plans are the client's
        read.plans[0].values[0] = 1.0


def test_the_checks_take_the_records_as_they_take_the_messages():
    rng = np.random.default_rng(1)
    limits = PlanLimits.of(PATROL)
    plans = _plans(rng, 6)
    read = read_request(serialize_message(Predict.Request(plans=plans))).plans
    for got, want in zip(check_plan_messages(read, H, limits),
                         check_plan_messages(plans, H, limits), strict=True):
        np.testing.assert_array_equal(got, want)
    plans[2] = _plans(rng, 1, n=1e4)[0]   # beyond the shaft's range: refused in its line
    read = read_request(serialize_message(Predict.Request(plans=plans))).plans
    with pytest.raises(PlanError) as by_message:
        check_plan_messages(plans, H, limits)
    with pytest.raises(PlanError, match=re.escape(str(by_message.value))):
        check_plan_messages(read, H, limits)
    assert str(by_message.value).startswith('plan 2: n[0] = 10000 outside')


def test_malformed_text_is_read_with_replacements_not_refused():
    request = Predict.Request(plans=[ControlPlan(plan_id='QQQQ', control_names=['n'])])
    cdr = serialize_message(request)
    assert cdr.count(b'QQQQ') == 1
    read = read_request(cdr.replace(b'QQQQ', b'Q\xff\xfeQ'))   # not UTF-8
    assert read.plans[0].plan_id == 'Q\ufffd\ufffdQ' and read.plans[0].control_names == ('n',)
