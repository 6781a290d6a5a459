"""
Launch arguments shared by the vessel launch files, taken from the nodes' parameter specs.

A node parameter offered as a launch argument keeps the default and description of the
node's YAML spec, so launch files never repeat a default. Imported by launch files
only: it needs the ``launch`` and ``launch_ros`` packages, which a node does not.
"""

from __future__ import annotations

from launch import LaunchContext
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.parameter_descriptions import ParameterValue

from vessel_ros_bridge.names import DEFAULT_NAMESPACE
from vessel_ros_bridge.parameters import load_specs, package_config

COMMON = {
    'namespace': (DEFAULT_NAMESPACE.lstrip('/'),
                  'Namespace of the nodes; every topic and service follows it '
                  '(relative names are placed under an enclosing PushRosNamespace).'),
    'use_sim_time': ('false', 'Time the nodes by /clock (the simulator publishes it).'),
    'frame_prefix': ('', "Prefix of the frame ids (e.g. 'boat1/' gives boat1/odom and "
                         'boat1/base_link), so vessels can share one TF tree.'),
}


def common_arguments(**defaults: str) -> list[DeclareLaunchArgument]:
    """Declare namespace, use_sim_time and frame_prefix, with optional other defaults."""
    return [DeclareLaunchArgument(name, default_value=defaults.get(name, default),
                                  description=description)
            for name, (default, description) in COMMON.items()]


def node_arguments(package: str, config: str, names: tuple[str, ...],
                   **defaults: str) -> list[DeclareLaunchArgument]:
    """Declare node parameters ``names`` as launch arguments with their specs' text."""
    specs = {spec.name: spec for spec in load_specs(package_config(package, config))}
    return [DeclareLaunchArgument(
        name, default_value=defaults.get(name, _text(specs[name].default)),
        description=specs[name].description) for name in names]


def node_parameters(package: str, config: str, names: tuple[str, ...],
                    context: LaunchContext | None = None) -> dict:
    """
    Map parameters ``names`` to their launch arguments, typed as the specs say.

    A parameter that may stay unset (spec default null) is passed only when its argument
    is not empty, which needs the launch ``context`` (build the node in an
    ``OpaqueFunction``).
    """
    specs = {spec.name: spec for spec in load_specs(package_config(package, config))}
    out = {}
    for name in names:
        spec = specs[name]
        if spec.default is None:
            if context is None:
                raise ValueError(f'{package}/{config}: {name} may stay unset; build the '
                                 f'node in an OpaqueFunction and pass its context')
            if not LaunchConfiguration(name).perform(context):
                continue
        out[name] = ParameterValue(LaunchConfiguration(name), value_type=spec.value_type)
    out['use_sim_time'] = ParameterValue(LaunchConfiguration('use_sim_time'), value_type=bool)
    return out


def prefixed_frame(frame: str) -> list:
    """Return ``frame_prefix`` + frame as a substitution."""
    return [LaunchConfiguration('frame_prefix'), frame]


def _text(default) -> str:
    # Launch arguments are strings; booleans as YAML reads them back; unset is empty.
    if default is None:
        return ''
    return str(default).lower() if isinstance(default, bool) else str(default)
