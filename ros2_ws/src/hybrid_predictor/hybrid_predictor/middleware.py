"""
The Fast DDS profile the predictor's what-if service runs with, chosen before rclpy starts.

A what-if answer is large (64 plans x 900 steps is about 6 MB). rmw_fastrtps keeps every
endpoint's history in PREALLOCATED_WITH_REALLOC memory: each history slot grows to the
largest answer it ever held and is never given back, so under a load of concurrent
requests the predictor's resident memory climbs with every new peak of answers in flight
(measured: +23 % in 10 minutes after warm-up). ``config/fastdds_predictor.xml`` gives the
service's endpoints DYNAMIC history memory (freed once delivered) and every other
endpoint rmw_fastrtps' own defaults.

A user's own Fast DDS configuration always wins: when any of the variables below is set,
or another RMW implementation is selected, nothing is changed.
"""

from __future__ import annotations

from collections.abc import MutableMapping
from pathlib import Path

PROFILE_FILE = 'fastdds_predictor.xml'
USER_SETTINGS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                 'RMW_FASTRTPS_USE_QOS_FROM_XML')
FAST_DDS = ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')


def use_service_profile(environ: MutableMapping[str, str], config_dir: Path) -> str:
    """
    Point Fast DDS at the predictor's profile in ``environ`` unless the user configured it.

    Return one line saying what was done, for the node's log. Must run before
    ``rclpy.init`` (rmw reads the variables when it creates the endpoints).
    """
    rmw = environ.get('RMW_IMPLEMENTATION', '')
    if rmw not in FAST_DDS:
        return f'middleware {rmw}: its own configuration'
    own = [name for name in USER_SETTINGS if environ.get(name)]
    if own:
        return f'Fast DDS configured by the user ({", ".join(own)}): profile left as set'
    profile = config_dir / PROFILE_FILE
    if not profile.is_file():
        raise FileNotFoundError(f'Fast DDS profile {profile} is missing from the install')
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile)
    environ['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'
    return f'Fast DDS profile {profile}: what-if answers in dynamic history memory'
