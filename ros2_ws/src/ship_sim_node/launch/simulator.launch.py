"""
Launch the vessel simulator alone.

``ros2 launch ship_sim_node simulator.launch.py [namespace:=vessel] [use_sim_time:=false]
[frame_prefix:=] [vessel:=] [real_time_factor:=1.0] [seed:=0] [publish_clock:=true]
[publish_truth:=false]``: the simulator publishes the topics of the vessel's recording
map under NAMESPACE (the patrol boat: NAMESPACE/odom, NAMESPACE/actuators, NAMESPACE/wind,
and NAMESPACE/odom_true) and the global /clock.
"""

from launch import LaunchDescription
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from vessel_ros_bridge.launch_args import (
    common_arguments,
    node_arguments,
    node_parameters,
    prefixed_frame,
)

PACKAGE, CONFIG = 'ship_sim_node', 'simulator.yaml'
ARGUMENTS = ('vessel', 'real_time_factor', 'seed', 'publish_clock', 'publish_truth')


def generate_launch_description():
    """Return the simulator node with its launch arguments."""
    parameters = node_parameters(PACKAGE, CONFIG, ARGUMENTS)
    parameters['world_frame'] = prefixed_frame('odom')
    parameters['body_frame'] = prefixed_frame('base_link')
    return LaunchDescription([
        *common_arguments(),
        *node_arguments(PACKAGE, CONFIG, ARGUMENTS),
        Node(package=PACKAGE, executable='simulator',
             namespace=LaunchConfiguration('namespace'), parameters=[parameters],
             output='screen'),
    ])
