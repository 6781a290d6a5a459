#!/usr/bin/env python3
"""
Publish a known, numbered sequence on the simulator's topics, for recorder tests.

Waits until every topic has a subscriber, publishes --count messages per topic at
--rate Hz (message i has header.stamp = --start-sec + i seconds, and i in a field:
odom pose.position.x, actuators velocity[0], wind vector.x), prints 'published N' and
then keeps its writers alive until SIGINT/SIGTERM, so a reliable subscriber still gets
any retransmission it needs.
"""

import argparse
import signal
import sys
import time

from geometry_msgs.msg import Vector3Stamped  # noqa: I001 - ROS message packages
from nav_msgs.msg import Odometry
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState


def main() -> int:
    """Publish, report, linger; return the exit status."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--count', type=int, default=50)
    parser.add_argument('--rate', type=float, default=50.0)
    parser.add_argument('--start-sec', type=int, default=1000)
    parser.add_argument('--wait', type=float, default=30.0, help='subscriber wait (s)')
    args = parser.parse_args()
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('bag_test_publisher')
    qos = QoSProfile(depth=max(args.count, 10), reliability=ReliabilityPolicy.RELIABLE)
    pubs = {'/vessel/odom': node.create_publisher(Odometry, '/vessel/odom', qos),
            '/vessel/actuators': node.create_publisher(JointState, '/vessel/actuators', qos),
            '/vessel/wind': node.create_publisher(Vector3Stamped, '/vessel/wind', qos)}
    deadline = time.monotonic() + args.wait
    while any(p.get_subscription_count() == 0 for p in pubs.values()) and not stop:
        if time.monotonic() > deadline:
            print('no subscriber', flush=True)
            return 1
        time.sleep(0.05)
    for i in range(args.count):
        if stop:
            break
        stamp = rclpy.time.Time(seconds=args.start_sec + i).to_msg()
        odom = Odometry()
        odom.header.stamp, odom.header.frame_id = stamp, 'odom'
        odom.child_frame_id = 'base_link'
        odom.pose.pose.position.x = float(i)
        odom.pose.pose.orientation.w = 1.0
        pubs['/vessel/odom'].publish(odom)
        joints = JointState()
        joints.header.stamp, joints.header.frame_id = stamp, 'base_link'
        joints.name = ['propeller', 'rudder_port', 'rudder_stbd']
        joints.position = [0.0, 0.1, 0.1]
        joints.velocity = [float(i), 0.0, 0.0]
        pubs['/vessel/actuators'].publish(joints)
        wind = Vector3Stamped()
        wind.header.stamp, wind.header.frame_id = stamp, 'base_link'
        wind.vector.x = float(i)
        pubs['/vessel/wind'].publish(wind)
        time.sleep(1.0 / args.rate)
    print(f'published {args.count}', flush=True)
    while not stop:
        time.sleep(0.05)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
