"""
Publishing without the interpreter lock while rcl sends: ``Outlet(publisher).publish(msg)``.

rclpy's ``Publisher.publish`` holds the lock while rcl hands the message to each
subscriber (0.5 ms at p50 for a quadrotor's Forecast and one subscriber); an Outlet
converts the message under the lock, as rclpy does, and sends it without, so the node's
other threads run meanwhile. The publisher stays rclpy's: its QoS, its graph events,
its destruction with the node.
"""

from __future__ import annotations

from what_if_c._outlet import publish

__all__ = ['Outlet']


class Outlet:
    """Send messages on an rclpy ``publisher`` with the interpreter lock released."""

    def __init__(self, publisher):
        from rclpy.type_support import check_for_type_support

        check_for_type_support(publisher.msg_type)
        self.publisher = publisher

    def publish(self, msg) -> None:
        """Publish ``msg`` (the publisher's type), as ``publisher.publish`` would."""
        if not isinstance(msg, self.publisher.msg_type):
            raise TypeError(f'expected {self.publisher.msg_type.__name__}, got '
                            f'{type(msg).__name__}')
        # Held as rclpy holds it while publishing: the publisher is not destroyed meanwhile.
        with self.publisher.handle:
            publish(self.publisher.handle.pointer, msg)
