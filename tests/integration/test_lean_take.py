"""Taking a request without building it in Python (vessel_ros_bridge.lean_take)."""

import json
import subprocess
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
    # that kept a reference would leak one per take. Counted in a process of its own:
    # in the test worker, garbage of earlier tests (collected during the loop) and other
    # threads held and dropped references to TAKEN too (a CI run saw 5 before, 4 after).
    out = subprocess.run([sys.executable, '-c', COUNT_TAKES], capture_output=True,
                         text=True, check=True)
    before, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert after == before


COUNT_TAKES = """
import json, sys
from rclpy.serialization import deserialize_message, serialize_message
from hybrid_predictor_interfaces.msg import ControlPlan
from hybrid_predictor_interfaces.srv import Predict
from vessel_ros_bridge.lean_take import TAKEN, lean_type
plan = ControlPlan(plan_id='p', control_names=['n', 'delta'], control_units=['rad/s', 'rad'],
                   values=[1.0, 0.1] * 90, step_period=10.0)
data = serialize_message(Predict.Request(plans=[plan] * 2, answer_period=10.0))
lean = lean_type(Predict.Request)
before = sys.getrefcount(TAKEN)
for _ in range(2000):
    deserialize_message(data, lean)
print(json.dumps([before, sys.getrefcount(TAKEN)]))
"""


def test_a_lean_type_made_before_its_type_was_ever_used_takes_lean():
    # In a fresh process nothing has loaded the type's C support yet: lean_type loads it.
    out = subprocess.run([sys.executable, '-c', LEAN_FIRST], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == 'TAKEN 8'


LEAN_FIRST = """
from rclpy.serialization import deserialize_message, serialize_message
from hybrid_predictor_interfaces.msg import ControlPlan
from hybrid_predictor_interfaces.srv import Predict
from vessel_ros_bridge.lean_take import lean_type
lean = lean_type(Predict.Request)
plan = ControlPlan(plan_id='p', values=[1.0, 0.1] * 90, step_period=10.0)
data = serialize_message(Predict.Request(plans=[plan] * 8, answer_period=10.0))
print(deserialize_message(data, lean), len(deserialize_message(data, Predict.Request).plans))
"""


def test_an_admitting_type_takes_whole_only_while_it_admits():
    admit = [True]
    seen = AdmittingType(Predict, lambda: admit[0])
    assert seen.Request is Predict.Request
    admit[0] = False
    assert seen.Request is not Predict.Request
    assert deserialize_message(serialize_message(request()), seen.Request) is TAKEN
    assert seen.Response is Predict.Response   # everything else is the type's own
