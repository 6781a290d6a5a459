"""
Input topics read in the order they arrived: ``open_inlet(node, topics)``.

The interpreter lock is released while an inlet waits and takes.

``Inlet.take(timeout)`` returns every message ready on any of the topics as
``(topic index, message, received ns)``, in the order DDS received them (the system
clock's ns), and ``[]`` when ``timeout`` s pass first; ``None`` once the inlet is closed.
One thread takes. ``Inlet.destroy()`` before the node is destroyed: it wakes a take under
way, then destroys the subscriptions. Why not rclpy's executors: ``_inlet``'s module doc.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from what_if_c._inlet import Inlet

if TYPE_CHECKING:
    from rclpy.qos import QoSProfile

__all__ = ['Inlet', 'open_inlet']


def open_inlet(node, topics: list[tuple[str, type, QoSProfile]]) -> Inlet:
    """
    Return an Inlet subscribing ``node`` to each ``(name, message class, QoS)`` of ``topics``.

    Names are resolved by rcl as rclpy's subscriptions' are (namespace, remapping). Of
    the QoS the depth and the reliability are used; the history is keep-last and the
    durability volatile, as a subscription's by default.
    """
    from rclpy.qos import HistoryPolicy, ReliabilityPolicy
    from rclpy.type_support import check_for_type_support

    rows = []
    for name, msg_class, qos in topics:
        if qos.history != HistoryPolicy.KEEP_LAST:
            raise ValueError(f'{name}: an inlet keeps the last messages only, not {qos.history}')
        check_for_type_support(msg_class)
        rows.append((name, msg_class, qos.depth, qos.reliability == ReliabilityPolicy.RELIABLE))
    return Inlet(node.handle.pointer, node.context.handle.pointer, rows)
