"""
Launch two simulated vessels, each with its own predictor, side by side on one graph.

``ros2 launch vessel_bringup two_vessels.launch.py [real_time_factor:=1.0]``: vessel
``boat1`` publishes /boat1/odom, ... and its predictor /boat1/forecast; ``boat2`` the
same under /boat2. Frame ids carry the namespace (boat1/odom, boat1/base_link), so both
share one TF tree. The nodes run on the wall clock and no simulator publishes /clock:
two simulators stepping independently are not one clock. So the simulators run in real
time: faster, their stamps would run ahead of the wall clock, and the predictors refuse
samples from the future.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import GroupAction, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource

from vessel_ros_bridge.launch_args import node_arguments

# (namespace, simulation seed): different seeds, so the vessels sail different seas.
VESSELS = (('boat1', '1'), ('boat2', '2'))


def vessel(namespace: str, seed: str) -> GroupAction:
    """Return one vessel's demo, scoped so its arguments do not leak to the other."""
    demo = Path(get_package_share_directory('vessel_bringup')) / 'launch' / 'demo.launch.py'
    return GroupAction([IncludeLaunchDescription(
        PythonLaunchDescriptionSource(str(demo)),
        launch_arguments={'namespace': namespace, 'frame_prefix': f'{namespace}/',
                          'seed': seed, 'use_sim_time': 'false',
                          'publish_clock': 'false'}.items())])


def generate_launch_description():
    """Return the two vessels."""
    return LaunchDescription([
        *node_arguments('ship_sim_node', 'simulator.yaml', ('real_time_factor',),
                        real_time_factor='1.0'),
        *(vessel(namespace, seed) for namespace, seed in VESSELS),
    ])
