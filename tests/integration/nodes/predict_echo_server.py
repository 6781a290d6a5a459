"""
A stand-in predictor for interface tests: answers Predict and publishes a Forecast.

Each forecast is a deterministic function of its plan (hybrid[k, :3] = the plan's row k,
physics = hybrid / 2), so the client can check that every field crossed the process
boundary intact and in order.
"""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException

from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
from hybrid_predictor_interfaces.srv import Predict

STATES = ['u', 'v', 'p', 'r', 'phi']
UNITS = ['m/s', 'm/s', 'rad/s', 'rad/s', 'rad']


def forecast_for(plan) -> Forecast:
    """Build the forecast this stand-in promises for a plan."""
    width = len(plan.control_names)
    horizon = len(plan.values) // width
    hybrid = []
    for k in range(horizon):
        hybrid += [*plan.values[k * width:(k + 1) * width], 0.0, 0.0]
    msg = Forecast(step_period=1.0, horizon=horizon, state_names=STATES, state_units=UNITS,
                   hybrid=hybrid, physics=[h / 2 for h in hybrid],
                   residual_bound=[0.1] * len(STATES),
                   x=[float(k) for k in range(horizon)], y=[0.0] * horizon,
                   heading=[0.0] * horizon, model_id='echo')
    msg.header.stamp = plan.header.stamp
    msg.header.frame_id = 'odom'
    return msg


def main() -> int:
    """Serve ~/predict and publish one forecast per second on /vessel/forecast."""
    rclpy.init()
    node = rclpy.create_node('predict_echo_server')

    def on_predict(request, response):
        if any(len(p.values) == 0 for p in request.plans):
            response.success = False
            response.message = 'empty plan'
            return response
        response.forecasts = [forecast_for(p) for p in request.plans]
        response.success = True
        response.message = f'{len(request.plans)} forecasts'
        return response

    node.create_service(Predict, '~/predict', on_predict)
    publisher = node.create_publisher(Forecast, '/vessel/forecast', 10)

    def publish():
        plan = ControlPlan(control_names=['n', 'delta_port', 'delta_stbd'],
                           values=[1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 3.0, 0.0, 0.0])
        publisher.publish(forecast_for(plan))

    node.create_timer(0.2, publish)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
