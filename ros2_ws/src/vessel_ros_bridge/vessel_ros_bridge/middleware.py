"""
A node's own Fast DDS profile, chosen before rclpy starts, unless the user set one.

Every node of the suite sends its writers' heartbeats every 0.1 s instead of Fast DDS's
default 3 s: a reliable writer repairs a sample its reader lost only after a heartbeat
and holds every later sample back until then, so one sample lost under load silenced a
topic for 3.2-4.2 s (measured: the predictor heard no odometry after a flood, and no
actuators from a simulator while it compiled its model). A user's own Fast DDS
configuration always wins: when any of the variables below is set, or another RMW
implementation is selected, nothing is changed.
"""

from __future__ import annotations

from collections.abc import MutableMapping
from pathlib import Path

USER_SETTINGS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                 'RMW_FASTRTPS_USE_QOS_FROM_XML')
FAST_DDS = ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')


def use_profile(environ: MutableMapping[str, str], profile: Path, what: str,
                qos_from_xml: bool = False) -> str:
    """
    Point Fast DDS at ``profile`` in ``environ`` unless the user configured it.

    ``qos_from_xml``: also let the profile's history memory and publish mode stand
    (RMW_FASTRTPS_USE_QOS_FROM_XML). Return one line saying what was done (``what`` the
    profile gives), for the node's log. Must run before ``rclpy.init``.
    """
    rmw = environ.get('RMW_IMPLEMENTATION', '')
    if rmw not in FAST_DDS:
        return f'middleware {rmw}: its own configuration'
    own = [name for name in USER_SETTINGS if environ.get(name)]
    if own:
        return f'Fast DDS configured by the user ({", ".join(own)}): profile left as set'
    if not profile.is_file():
        raise FileNotFoundError(f'Fast DDS profile {profile} is missing from the install')
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile)
    if qos_from_xml:
        environ['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'
    return f'Fast DDS profile {profile}: {what}'
