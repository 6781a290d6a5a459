"""
The rate benchmark's receiver: when each forecast arrived, noted in a process of its own.

``python offline/benchmarks/rate_receiver.py OUT DEPTH`` subscribes to the predictor's
forecast topic in the nodes' namespace (keeping the last DEPTH) and notes, for each
forecast, its state's stamp, when its callback ran and when DDS received it (s, the
system clock); interrupted (SIGINT), it writes ``{"arrivals": {stamp: s}, "receipts":
{stamp: s}}`` to OUT and exits 0. Apart from the replay that publishes the vehicle's
states (``node_rate.measure``), as a controller is apart from the vehicle: in one
process, taking each 63 kB Crazyflie forecast held the interpreter the replay's next
state waited for.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time


def main(argv: list[str] | None = None) -> int:
    """Note every forecast's arrival until interrupted; then write them to OUT."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('out', type=Path, help='JSON file written when interrupted')
    parser.add_argument('depth', type=int, help='forecasts the subscription keeps')
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.qos import QoSProfile

    from hybrid_predictor.node import FORECAST_TOPIC
    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_ros_bridge import messages as m
    from vessel_ros_bridge.lifecycle import run_node

    arrivals: dict[float, float] = {}
    receipts: dict[float, float] = {}

    def on_forecast(msg, info) -> None:
        stamp = round(m.seconds_from_stamp(msg.header.stamp), 6)
        arrivals.setdefault(stamp, time.time())
        receipts.setdefault(stamp, info['received_timestamp'] * 1e-9)

    def receiver(namespace: str):
        node = rclpy.create_node('bench_rate_receiver', namespace=namespace)
        node.create_subscription(Forecast, FORECAST_TOPIC, on_forecast,
                                 QoSProfile(depth=args.depth))
        return node

    try:
        return run_node(receiver, 'rate_receiver')   # in the nodes' namespace
    finally:
        args.out.write_text(json.dumps({'arrivals': arrivals, 'receipts': receipts}))


if __name__ == '__main__':
    sys.exit(main())
