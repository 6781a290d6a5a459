"""Taking a request without building it in Python (vessel_ros_bridge.lean_take)."""

import sys

import pytest
from rclpy.serialization import deserialize_message, serialize_message

from hybrid_predictor_interfaces.msg import ControlPlan
from hybrid_predictor_interfaces.srv import Predict
from vessel_ros_bridge.lean_take import TAKEN, AdmittingType, lean_type

pytestmark = pytest.mark.ros   # the installed interfaces and bridge


def request(plans: int = 8) -> Predict.Request:
    plan = ControlPlan(plan_id='p', control_names=['n', 'delta'], control_units=['rad/s', 'rad'],
                       values=[1.0, 0.1] * 90, step_period=10.0)
    return Predict.Request(plans=[plan] * plans, answer_period=10.0)


def test_a_lean_take_reads_the_message_in_c_and_gives_taken():
    data = serialize_message(request())
    assert deserialize_message(data, lean_type(Predict.Request)) is TAKEN
    # The real type still comes out whole: the stand-in changed nothing of it.
    whole = deserialize_message(data, Predict.Request)
    assert len(whole.plans) == 8 and whole.plans[0].plan_id == 'p'
    assert list(whole.plans[0].values[:2]) == [1.0, 0.1]


def test_lean_takes_hold_no_reference_they_do_not_give_back():
    # A C conversion that returned a borrowed reference would free TAKEN (a crash); one
    # that kept a reference would leak one per take.
    lean = lean_type(Predict.Request)
    data = serialize_message(request(2))
    before = sys.getrefcount(TAKEN)
    for _ in range(2000):
        deserialize_message(data, lean)
    assert sys.getrefcount(TAKEN) == before


def test_an_admitting_type_takes_whole_only_while_it_admits():
    admit = [True]
    seen = AdmittingType(Predict, lambda: admit[0])
    assert seen.Request is Predict.Request
    admit[0] = False
    assert seen.Request is not Predict.Request
    assert deserialize_message(serialize_message(request()), seen.Request) is TAKEN
    assert seen.Response is Predict.Response   # everything else is the type's own
