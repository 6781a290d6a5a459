"""
A stand-in for the predictor that answers each state at once: the benchmark's floor.

``python offline/benchmarks/stand_in.py VEHICLE`` subscribes to the vehicle's input topics
(its topic map's, as the predictor reads them) and publishes, for every state (the map's
state entry), an empty Forecast with the state's stamp on the predictor's forecast topic.
Timed by ``node_rate.measure`` like the predictor, it gives what the replay, DDS and the
receiving client cost with no forecast made: the floor under any predictor's delay.
"""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    """Answer states until interrupted."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('vehicle', help='vehicle file name or path')
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from hybrid_predictor.input_window import state_topic
    from hybrid_predictor.node import FORECAST_TOPIC
    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel
    from vessel_ros_bridge import messages
    from vessel_ros_bridge.names import DEFAULT_NAMESPACE

    topic_map = topic_map_for(load_vessel(args.vehicle))
    state = state_topic(topic_map)
    rclpy.init()
    node = rclpy.create_node('stand_in_predictor', namespace=DEFAULT_NAMESPACE)
    publisher = node.create_publisher(Forecast, FORECAST_TOPIC, 10)

    def answer(msg) -> None:
        forecast = Forecast()
        forecast.header.stamp = msg.header.stamp
        publisher.publish(forecast)

    # Every input topic read, as the predictor reads them; the state answered.
    for topic, msg_class in messages.message_types(topic_map).items():
        node.create_subscription(msg_class, topic, answer if topic == state else (
            lambda msg: None), 100)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
