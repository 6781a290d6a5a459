"""
Launch the whole suite for one vessel: simulator, predictor and, optionally, a recorder.

``ros2 launch vessel_bringup demo.launch.py [namespace:=vessel] [use_sim_time:=true]
[real_time_factor:=10.0] [record:=BAG_DIR]``, plus every argument of
``simulator.launch.py`` and ``predictor.launch.py``. With the defaults the topics are
/vessel/odom, /vessel/actuators, /vessel/wind, /vessel/forecast, ... and the nodes time
themselves by the simulator's /clock. ``record:=DIR`` also runs the recorder
(``vessel_recorder record``) on the namespace's odom, actuators and wind topics.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.utilities import make_namespace_absolute, prefix_namespace

from vessel_ros_bridge import messages
from vessel_ros_bridge.launch_args import common_arguments, node_arguments

# A faster-than-real-time simulator, whose /clock the nodes follow: forecasts start
# after a few seconds instead of the minute a real-time window takes to fill.
DEMO_DEFAULTS = {'use_sim_time': 'true', 'real_time_factor': '10.0'}
RECORDED = (messages.ODOM_TOPIC, messages.ACTUATORS_TOPIC, messages.WIND_TOPIC)


def included(package: str, launch_file: str) -> IncludeLaunchDescription:
    """Include a package's launch file; it sees this file's launch arguments."""
    path = Path(get_package_share_directory(package)) / 'launch' / launch_file
    return IncludeLaunchDescription(PythonLaunchDescriptionSource(str(path)))


def recorder(context):
    """Return the recorder process for the namespace's topics, if ``record`` names a bag."""
    out = context.perform_substitution(LaunchConfiguration('record'))
    if not out:
        return []
    namespace = make_namespace_absolute(prefix_namespace(
        context.launch_configurations.get('ros_namespace'),
        context.perform_substitution(LaunchConfiguration('namespace'))))
    topics = [prefix_namespace(namespace, topic) for topic in RECORDED]
    arguments = ['--out', out, '--topics', *topics]
    if context.perform_substitution(LaunchConfiguration('use_sim_time')).lower() == 'true':
        arguments.append('--use-sim-time')
    return [Node(package='vessel_recorder', executable='record', arguments=arguments,
                 output='screen')]


def generate_launch_description():
    """Return simulator + predictor (+ recorder) with the demo's defaults."""
    return LaunchDescription([
        *common_arguments(**DEMO_DEFAULTS),
        *node_arguments('ship_sim_node', 'simulator.yaml', ('real_time_factor',),
                        **DEMO_DEFAULTS),
        DeclareLaunchArgument('record', default_value='',
                              description='Bag directory to record into; empty: no recorder.'),
        included('ship_sim_node', 'simulator.launch.py'),
        included('hybrid_predictor', 'predictor.launch.py'),
        OpaqueFunction(function=recorder),
    ])
