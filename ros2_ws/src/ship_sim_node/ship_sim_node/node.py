"""
The simulator node: a thin ROS 2 adapter around ``vessel_physics.simulation``.

Simulates one vessel of any family -- the patrol boat unless ``vessel`` (a vessel file's
name or path) or ``scenario`` (a simulation YAML) says otherwise -- and publishes, once
per output period, what its sensors would: the topics, message types, fields, frames
and scales of the vessel file's recording map (``recordings.topics``, written by
``vessel_datasets.topic_messages``), plus the global ``/clock`` and, optionally, a
noise-free copy of the state topic (``<state topic>_true``). Commands on ``cmd`` (a
message of the actuators' topic type, read with the same map entries: for the patrol
boat a JointState) override the simulated operator while they keep arriving.
``~/reset`` (std_srvs/Trigger) starts the run again. Topics the vessel file names under
``/vessel`` are relative to the node's namespace (``-r __ns:=/boat1``). All numerics
live in ``vessel_physics``; this module only moves values between it and messages.

A tick that comes late is made up at the next (``pacing.Pacer``): the simulated time
keeps the wall clock's pace on average (a quadrotor's 100 Hz on a busy machine); a node
that cannot keep up at all says so and lets the missed periods go.
"""

from __future__ import annotations

from functools import partial
import os
import sys
import time

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from std_srvs.srv import Trigger

from ship_sim_node.command_gate import CommandGate, CommandLimits
from ship_sim_node.pacing import Pacer
from vessel_datasets.topic_map import ACTUATOR_PREFIX, TopicMapError, topic_map_for
from vessel_datasets.topic_messages import MessageWriter, channel_reader, channel_values
from vessel_physics.errors import ConfigError
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.simulator import Simulator
from vessel_ros_bridge import messages
from vessel_ros_bridge.lifecycle import run_node
from vessel_ros_bridge.middleware import use_profile
from vessel_ros_bridge.names import node_topic
from vessel_ros_bridge.parameters import declare_from_specs, load_specs, package_config

NODE_NAME = 'simulator'
PROFILE_FILE = 'fastdds_simulator.xml'   # heartbeats every 0.1 s (vessel_ros_bridge.middleware)
TRUE_SUFFIX = '_true'


class SimulatorNode(Node):
    """Run one simulated vessel and publish what its sensors would."""

    def __init__(self, middleware_note: str = '', **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        if middleware_note:   # which Fast DDS profile: ours, or the user's
            self.get_logger().info(middleware_note)
        params = declare_from_specs(
            self, load_specs(package_config('ship_sim_node', 'simulator.yaml')))
        self._params = params
        config = load_simulation(params['scenario'] or None, params['vessel'] or None)
        self.vessel = config.vessel
        self.sim = Simulator(config, n_runs=1, seed=params['seed'],
                             run_offset=params['run_index'])
        self.gate = CommandGate(CommandLimits({name: (low, high) for name, (
            low, high, _, _) in config.actuators.items()}), params['command_timeout'])
        self.epoch = params['start_time'] or time.time()
        self.output_period = 1.0 / config.output_rate_hz

        topic_map = topic_map_for(self.vessel)
        types = messages.message_types(topic_map)
        self.writer = MessageWriter(topic_map, types, params['world_frame'],
                                    params['body_frame'])
        self.publishers_ = {topic: self.create_publisher(types[topic], node_topic(topic), 10)
                            for topic in self.writer.topics}
        state_topic = self.writer.topics[-1]
        self.truth_pub = (self.create_publisher(types[state_topic],
                                                node_topic(state_topic) + TRUE_SUFFIX, 10)
                          if params['publish_truth'] else None)
        self.clock_pub = (self.create_publisher(ClockMsg, '/clock', 10)
                          if params['publish_clock'] else None)
        command_topic = next(e.topic for e in topic_map.entries if e.group == 'actuators')
        self._read_command = channel_reader(topic_map, command_topic)
        self.create_subscription(types[command_topic], messages.COMMAND_TOPIC,
                                 self._on_command, 10)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.timer = None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.pacer = Pacer(self.output_period, params['real_time_factor'])
        self._start_timer(params['real_time_factor'])
        self._publish(self.sim.sample())
        self.get_logger().info(
            f'simulating {self.vessel.name} ({config.physics.family.title}) seed '
            f'{params["seed"]} run {params["run_index"]} at {params["real_time_factor"]:g}x '
            f'real time on {", ".join(self.writer.topics)}')

    # ------------------------------------------------------------------ stepping
    def _start_timer(self, real_time_factor: float) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
        # A steady wall clock drives the stepping: this node *is* the source of /clock,
        # so a sim-time timer would wait for itself.
        self.timer = self.create_timer(self.output_period / real_time_factor, self._tick,
                                       clock=self._steady)
        self.pacer.restart(self._now(), self.sim.t, real_time_factor)

    def _now(self) -> float:
        return self._steady.now().nanoseconds * 1e-9

    def _tick(self) -> None:
        skipped = self.pacer.skipped
        for _ in range(self.pacer.due(self._now(), self.sim.t)):
            sample = self.sim.advance(self.gate.active(self.sim.t))
            self._publish(sample)
        if self.pacer.skipped > skipped:
            self.get_logger().warning(
                f'cannot keep {self.pacer.real_time_factor:g}x real time: '
                f'{self.pacer.skipped} output periods let go so far', throttle_duration_sec=10.0)

    def _publish(self, sample) -> None:
        values = {key: float(value[0]) for key, value in sample.items()}
        stamp = messages.stamp_from_seconds(self.epoch + values['t'])
        if self.clock_pub is not None:
            self.clock_pub.publish(ClockMsg(clock=stamp))
        channels = channel_values(values, self.writer.topic_map)
        # The state topic goes last: a consumer holding a state has the whole sample.
        if self.truth_pub is not None:
            truth = {**values, **{k: values[k + TRUE_SUFFIX] for k in self.sim.true_keys}}
            self.truth_pub.publish(self.writer.message(
                self.writer.topics[-1], channel_values(truth, self.writer.topic_map), stamp))
        for topic, publisher in self.publishers_.items():
            publisher.publish(self.writer.message(topic, channels, stamp))

    # ------------------------------------------------------------------ inputs
    def _on_command(self, msg) -> None:
        try:
            read = self._read_command(msg)
            command = {k[len(ACTUATOR_PREFIX):]: v for k, v in read.items()
                       if k.startswith(ACTUATOR_PREFIX)}
            if not command:
                raise ValueError(f'names none of the actuators {list(self.sim.actuators)}')
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
        self.pacer.restart(self._now(), self.sim.t)
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
    note = use_profile(os.environ, package_config('ship_sim_node', PROFILE_FILE),
                       'heartbeats every 0.1 s')
    return run_node(partial(SimulatorNode, middleware_note=note), NODE_NAME,
                    (ConfigError, TopicMapError, ValueError), args)


if __name__ == '__main__':
    sys.exit(main())
