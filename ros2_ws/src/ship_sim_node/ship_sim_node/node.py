"""
The simulator node: a thin ROS 2 adapter around ``vessel_physics.simulator``.

Publishes, once per simulated second (REP-103/105 frames, docs/conventions.md):
``odom`` (nav_msgs/Odometry, measured), ``actuators`` (sensor_msgs/JointState), ``wind``
(geometry_msgs/Vector3Stamped, measured true wind), the global ``/clock`` and,
optionally, ``odom_true`` (noise-free). Commands on ``cmd`` (JointState) override the
simulated operator while they keep arriving. ``~/reset`` (std_srvs/Trigger) starts the
run again. Names are relative to the node's namespace, ``/vessel`` unless moved
(``-r __ns:=/boat1``). All numerics live in
``vessel_physics``; this module only moves values between it and messages.
"""

from __future__ import annotations

import sys
import time

from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from ship_sim_node.command_gate import CommandGate, CommandLimits
from vessel_physics.config import ConfigError, load_config
from vessel_physics.simulator import Simulator
from vessel_ros_bridge import messages
from vessel_ros_bridge.lifecycle import run_node
from vessel_ros_bridge.parameters import declare_from_specs, load_specs, package_config

NODE_NAME = 'simulator'


class SimulatorNode(Node):
    """Run one simulated vessel and publish what its sensors would."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        params = declare_from_specs(
            self, load_specs(package_config('ship_sim_node', 'simulator.yaml')))
        self._params = params
        config = load_config(params['scenario'] or None)
        self.sim = Simulator(config, n_runs=1, seed=params['seed'],
                             run_offset=params['run_index'])
        vessel = config.vessel
        self.gate = CommandGate(CommandLimits(vessel.shaft_max_speed, vessel.rudder_max_angle),
                                params['command_timeout'])
        self.epoch = params['start_time'] or time.time()
        self.output_period = 1.0 / config.output_rate_hz

        self.odom_pub = self.create_publisher(Odometry, messages.ODOM_TOPIC, 10)
        self.truth_pub = (self.create_publisher(Odometry, messages.ODOM_TRUE_TOPIC, 10)
                          if params['publish_truth'] else None)
        self.actuator_pub = self.create_publisher(JointState, messages.ACTUATORS_TOPIC, 10)
        self.wind_pub = self.create_publisher(Vector3Stamped, messages.WIND_TOPIC, 10)
        self.clock_pub = (self.create_publisher(ClockMsg, '/clock', 10)
                          if params['publish_clock'] else None)
        self.create_subscription(JointState, messages.COMMAND_TOPIC, self._on_command, 10)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.timer = None
        self._start_timer(params['real_time_factor'])
        self._publish(self.sim.sample())
        self.get_logger().info(
            f'simulating seed {params["seed"]} run {params["run_index"]} at '
            f'{params["real_time_factor"]:g}x real time')

    # ------------------------------------------------------------------ stepping
    def _start_timer(self, real_time_factor: float) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
        # A steady wall clock drives the stepping: this node *is* the source of /clock,
        # so a sim-time timer would wait for itself.
        self.timer = self.create_timer(self.output_period / real_time_factor, self._tick,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _tick(self) -> None:
        sample = self.sim.advance(self.gate.active(self.sim.t))
        self._publish(sample)

    def _publish(self, sample) -> None:
        values = {key: float(value[0]) for key, value in sample.items()}
        stamp = messages.stamp_from_seconds(self.epoch + values['t'])
        world, body = self._params['world_frame'], self._params['body_frame']
        if self.clock_pub is not None:
            self.clock_pub.publish(ClockMsg(clock=stamp))
        # The state goes last: a consumer holding a state has the whole sample.
        self.actuator_pub.publish(messages.joint_state_from_actuators(values, stamp))
        self.wind_pub.publish(messages.wind_from_measurement(
            values['wind_speed'], values['wind_dir_cos'], values['wind_dir_sin'], stamp, body))
        if self.truth_pub is not None:
            truth = {key: values[key + '_true'] for key in ('u', 'v', 'p', 'r', 'phi', 'psi',
                                                             'x', 'y')}
            self.truth_pub.publish(messages.odometry_from_state(truth, stamp, world, body))
        self.odom_pub.publish(messages.odometry_from_state(values, stamp, world, body))

    # ------------------------------------------------------------------ inputs
    def _on_command(self, msg: JointState) -> None:
        try:
            command = messages.actuators_from_joint_state(msg)
        except ValueError as exc:
            reason = str(exc)
        else:
            reason = self.gate.offer(command, self.sim.t)
        if reason:
            self.get_logger().warning(f'rejected command on {messages.COMMAND_TOPIC}: {reason}; '
                                      'the last good command holds', throttle_duration_sec=5.0)

    def _on_reset(self, request, response):
        self.sim.reset(self.get_parameter('seed').value)
        self.gate.clear()
        self._publish(self.sim.sample())
        response.success = True
        response.message = f'reset to t = 0 with seed {self.sim.seed}'
        return response

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == 'real_time_factor':
                self._start_timer(parameter.value)
            elif parameter.name == 'command_timeout':
                self.gate.timeout_s = parameter.value
        return SetParametersResult(successful=True)


def main(args=None) -> int:
    """Run the simulator node until interrupted; exit 2 with one line on a bad config."""
    return run_node(SimulatorNode, NODE_NAME, (ConfigError, ValueError), args)


if __name__ == '__main__':
    sys.exit(main())
