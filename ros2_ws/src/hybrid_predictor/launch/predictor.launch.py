"""
Launch the forecast predictor alone, for a simulated or a real vessel.

``ros2 launch hybrid_predictor predictor.launch.py [namespace:=vessel]
[use_sim_time:=false] [frame_prefix:=] [vessel:=FILE] [model_path:=FILE]
[relative_threshold:=T]``: the predictor reads NAMESPACE/odom, NAMESPACE/actuators,
NAMESPACE/wind (the vessel file's topics) and NAMESPACE/control_plan, publishes
NAMESPACE/forecast and NAMESPACE/forecast/path and serves NAMESPACE/predictor/predict.
"""

from launch import LaunchDescription
from launch.actions import OpaqueFunction
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


def predictor(context, *_args) -> list[Node]:
    """Return the predictor node; an empty relative_threshold leaves the model's own."""
    parameters = node_parameters(PACKAGE, CONFIG, ARGUMENTS, context)
    parameters['world_frame'] = prefixed_frame('odom')
    parameters['body_frame'] = prefixed_frame('base_link')
    return [Node(package=PACKAGE, executable='predictor',
                 namespace=LaunchConfiguration('namespace'), parameters=[parameters],
                 output='screen')]


def generate_launch_description():
    """Return the predictor node with its launch arguments."""
    return LaunchDescription([
        *common_arguments(),
        *node_arguments(PACKAGE, CONFIG, ARGUMENTS),
        OpaqueFunction(function=predictor),
    ])
