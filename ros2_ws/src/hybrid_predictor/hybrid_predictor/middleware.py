"""
The Fast DDS profile the predictor's what-if service runs with, chosen before rclpy starts.

A what-if answer is large (64 plans x 900 steps is about 6 MB). rmw_fastrtps keeps every
endpoint's history in PREALLOCATED_WITH_REALLOC memory: each history slot grows to the
largest answer it ever held and is never given back, so under a load of concurrent
requests the predictor's resident memory climbs with every new peak of answers in flight
(measured: +23 % in 10 minutes after warm-up). ``config/fastdds_predictor.xml`` gives the
service's endpoints DYNAMIC history memory (freed once delivered) and every other
endpoint rmw_fastrtps' own defaults; every writer sends its heartbeats every 0.1 s
(``vessel_ros_bridge.middleware``). Its shared-memory segment is 32 MiB, not 512 kB:
answers in flight overwrote each other's unread buffers there, and a lost answer waited
for its repair.

A process that asks ~/predict calls ``use_client_profile`` before ``rclpy.init``: its
requests in flight need the same room (``config/fastdds_what_if_client.xml``).

A user's own Fast DDS configuration always wins (``vessel_ros_bridge.middleware``).
"""

from __future__ import annotations

from collections.abc import MutableMapping
from pathlib import Path

from vessel_ros_bridge.middleware import use_profile

PROFILE_FILE = 'fastdds_predictor.xml'
CLIENT_PROFILE_FILE = 'fastdds_what_if_client.xml'


def use_service_profile(environ: MutableMapping[str, str],
                        config_dir: Path | None = None) -> str:
    """
    Point Fast DDS at the predictor's profile in ``environ`` unless the user configured it.

    ``config_dir`` defaults to the installed package's. Return one line saying what was
    done, for the node's log. Must run before ``rclpy.init`` (rmw reads the variables
    when it creates the endpoints).
    """
    return use_profile(environ, profile_path(PROFILE_FILE, config_dir),
                       'what-if answers in dynamic history memory, a 32 MiB shared-memory '
                       'segment, heartbeats every 0.1 s', qos_from_xml=True)


def use_client_profile(environ: MutableMapping[str, str], config_dir: Path | None = None) -> str:
    """
    Point Fast DDS at the what-if client's profile in ``environ`` unless the user set one.

    For a process that sends ~/predict requests; ``config_dir`` defaults to the installed
    package's. Return one line saying what was done. Must run before ``rclpy.init``.
    """
    return use_profile(environ, profile_path(CLIENT_PROFILE_FILE, config_dir),
                       'a 32 MiB shared-memory segment for requests in flight, heartbeats '
                       'every 0.1 s')


def profile_path(profile: str, config_dir: Path | None) -> Path:
    """Return ``profile`` in ``config_dir``, or in the installed package's config directory."""
    if config_dir is not None:
        return config_dir / profile
    from vessel_ros_bridge.parameters import package_config

    return package_config('hybrid_predictor', profile)
