"""
The namespace the vessel nodes run in, and how recorded topic names map onto it.

Nodes name their topics relatively (``odom``, ``forecast``), so the names follow the
node's namespace. Started without one, a node runs in ``DEFAULT_NAMESPACE`` and its
topics are where recordings, vessel files and docs expect them (``/vessel/odom``);
``--ros-args -r __ns:=/boat1`` moves all of them to ``/boat1/...``. Vessel files name
topics as they appear in bags, absolutely; ``node_topic`` turns such a name back into
the one a node subscribes to.
"""

from __future__ import annotations

DEFAULT_NAMESPACE = '/vessel'


def node_topic(recorded: str) -> str:
    """
    Return the name a node subscribes to for a topic a vessel file names.

    A name under ``DEFAULT_NAMESPACE`` (``/vessel/odom``) becomes relative (``odom``) and
    so follows the node's namespace; any other name (a real vessel's ``/sensor``) is
    kept, absolute, because it belongs to that vessel's own drivers.
    """
    prefix = DEFAULT_NAMESPACE + '/'
    return recorded[len(prefix):] if recorded.startswith(prefix) else recorded
