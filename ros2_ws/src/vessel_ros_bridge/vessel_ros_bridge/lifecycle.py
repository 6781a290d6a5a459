"""Run a node until SIGINT/SIGTERM, the same way for every vessel node."""

from __future__ import annotations

from collections.abc import Callable
import sys

import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException

from vessel_ros_bridge.allocator import share_malloc_arenas
from vessel_ros_bridge.names import DEFAULT_NAMESPACE


def run_node(make_node: Callable, program: str, expected_errors: tuple = (),
             args=None, make_executor: Callable | None = None) -> int:
    """
    Create a node with ``make_node()``, spin it, and shut down cleanly; return an exit code.

    The node starts in ``DEFAULT_NAMESPACE`` unless the command line moves it
    (``--ros-args -r __ns:=/boat1``; a remapped namespace overrides the constructor's).

    Set-up errors of the kinds in ``expected_errors`` (and invalid parameter values) end
    the program with one line ``PROGRAM: error: ...`` and exit code 2. A signal that
    lands while a callback is publishing makes that publish fail on the already shut
    down context; such an error is part of stopping, not a fault, and exits 0.
    ``make_executor(node)`` gives the executor to spin in (default: rclpy's
    single-threaded one). The process's threads share two malloc arenas
    (``allocator``), so the node's resident memory follows what it holds.
    """
    allocator_note = share_malloc_arenas()
    rclpy.init(args=args)
    node = None
    try:
        node = make_node(namespace=DEFAULT_NAMESPACE)
        node.get_logger().info(allocator_note)
        rclpy.spin(node, make_executor(node) if make_executor else None)
    except (InvalidParameterValueException, *expected_errors) as exc:
        print(f'{program}: error: {exc}', file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
