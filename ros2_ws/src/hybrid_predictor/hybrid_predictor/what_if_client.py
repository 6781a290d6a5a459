"""
Asking ``~/predict`` from a script or a controller that waits for its answer.

Two things a caller must handle, done here once:

- "busy": the node refuses requests beyond its capacity at once and says, in
  ``retry_after``, when to come back; the caller comes back then.
- A request answered into the void: Fast DDS drops a response when the service's
  response writer has not matched the client's reader within 100 ms, and
  ``wait_for_service`` only sees the client's side of that match (ros2/ros2#1253,
  ros2/rmw_fastrtps#842), so the first request of a new client can go unanswered.
  A what-if request changes nothing on the node, so it is sent again when no answer
  came within ``resend_after`` seconds.

Times are seconds of wall time. For a node no other executor spins (a controller that
spins its node elsewhere calls ``call_async`` and follows the same two rules).
"""

from __future__ import annotations

import time


def is_busy(answer) -> bool:
    """Return whether a Predict answer refused the request for load."""
    return not answer.success and answer.message.startswith('busy')


def ask(node, client, request, timeout: float = 60.0, resend_after: float = 10.0):
    """
    Return the first answer to ``request`` that is not "busy", or None.

    Waits at most ``timeout`` s in all; returns the last "busy" answer if every one was
    busy until then, None if nothing was answered.
    """
    from rclpy.executors import SingleThreadedExecutor

    if not 0 < resend_after:
        raise ValueError(f'resend_after must be > 0 s, got {resend_after}')
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    answer = None
    try:
        while time.monotonic() < deadline:
            future = client.call_async(request)
            executor.spin_until_future_complete(
                future, timeout_sec=min(resend_after, deadline - time.monotonic()))
            if not future.done():
                client.remove_pending_request(future)   # its answer, if late, is dropped
                continue
            answer = future.result()
            if not is_busy(answer):
                return answer
            come_back = min(time.monotonic() + answer.retry_after, deadline)
            while time.monotonic() < come_back:
                executor.spin_once(timeout_sec=max(0.0, come_back - time.monotonic()))
        return answer
    finally:
        executor.remove_node(node)
        executor.shutdown()
