"""
Launch the forecast predictor alone, for a simulated or a real vessel.

``ros2 launch hybrid_predictor predictor.launch.py [namespace:=vessel]
[use_sim_time:=false] [frame_prefix:=] [vessel:=FILE] [model_path:=FILE]
[relative_threshold:=0.15]``: the predictor reads NAMESPACE/odom, NAMESPACE/actuators,
NAMESPACE/wind (the vessel file's topics) and NAMESPACE/control_plan, publishes
NAMESPACE/forecast and NAMESPACE/forecast/path and serves NAMESPACE/predictor/predict.
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

PACKAGE, CONFIG = 'hybrid_predictor', 'predictor.yaml'
ARGUMENTS = ('vessel', 'model_path', 'relative_threshold')


def generate_launch_description():
    """Return the predictor node with its launch arguments."""
    parameters = node_parameters(PACKAGE, CONFIG, ARGUMENTS)
    parameters['world_frame'] = prefixed_frame('odom')
    return LaunchDescription([
        *common_arguments(),
        *node_arguments(PACKAGE, CONFIG, ARGUMENTS),
        Node(package=PACKAGE, executable='predictor',
             namespace=LaunchConfiguration('namespace'), parameters=[parameters],
             output='screen'),
    ])
