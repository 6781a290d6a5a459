"""Forecast and Predict cross a process boundary over DDS intact."""

from pathlib import Path

import pytest

from .conftest import answer_of, spin_until

pytestmark = pytest.mark.ros

ECHO_SERVER = Path(__file__).parent / 'nodes' / 'predict_echo_server.py'


def make_plan(shaft_speed):
    from hybrid_predictor_interfaces.msg import ControlPlan

    values = [[n, 0.01 * k, -0.01 * k] for k, n in enumerate(shaft_speed)]
    return ControlPlan(control_names=['n', 'delta_port', 'delta_stbd'],
                       control_units=['rad/s', 'rad', 'rad'],
                       values=[x for row in values for x in row])


def call(node, client, request):
    return answer_of(node, client, request, resend_after=5.0)   # the echo answers at once


def test_predict_round_trip_answers_one_forecast_per_plan(launcher, ros_node):
    from hybrid_predictor_interfaces.srv import Predict

    launcher.start_script(ECHO_SERVER)
    client = ros_node.create_client(Predict, '/predict_echo_server/predict')
    assert client.wait_for_service(timeout_sec=20), 'service never appeared'

    plans = [make_plan([10.0, 11.0, 12.0]), make_plan([20.0, 21.0])]
    response = call(ros_node, client, Predict.Request(plans=plans))

    assert response.success, response.message
    assert [f.horizon for f in response.forecasts] == [3, 2]
    first = response.forecasts[0]
    assert list(first.state_names) == ['u', 'v', 'p', 'r', 'phi']
    hybrid = [list(first.hybrid[i:i + 5]) for i in range(0, len(first.hybrid), 5)]
    assert [row[0] for row in hybrid] == [10.0, 11.0, 12.0]
    assert hybrid[2][1] == pytest.approx(0.02) and hybrid[2][2] == pytest.approx(-0.02)
    assert list(first.physics) == pytest.approx([h / 2 for h in first.hybrid])
    assert response.forecasts[1].hybrid[5] == 21.0


def test_predict_error_response_is_an_answer_not_a_crash(launcher, ros_node):
    from hybrid_predictor_interfaces.srv import Predict

    server = launcher.start_script(ECHO_SERVER)
    client = ros_node.create_client(Predict, '/predict_echo_server/predict')
    assert client.wait_for_service(timeout_sec=20)

    bad = call(ros_node, client, Predict.Request(plans=[make_plan([])]))
    assert not bad.success and bad.message == 'empty plan' and len(bad.forecasts) == 0
    good = call(ros_node, client, Predict.Request(plans=[make_plan([1.0])]))
    assert good.success and server.alive()


def test_forecast_topic_delivers_the_whole_message(launcher, ros_node):
    from hybrid_predictor_interfaces.msg import Forecast

    received = []
    ros_node.create_subscription(Forecast, '/vessel/forecast', received.append, 10)
    launcher.start_script(ECHO_SERVER)

    assert spin_until(ros_node, lambda: received, 20.0), 'no forecast arrived'
    msg = received[0]
    assert msg.header.frame_id == 'odom' and msg.step_period == 1.0
    assert len(msg.hybrid) == msg.horizon * len(msg.state_names) == 15
    assert list(msg.x) == [0.0, 1.0, 2.0] and list(msg.residual_bound) == [0.1] * 5
