"""
rclpy's MultiThreadedExecutor without its queued-task storm (ros2/rclpy#1452).

In rclpy 7.1 (Jazzy) every callback is a task the executor keeps until it is done, and
``Executor._wait_for_ready_callbacks`` yields again every kept task that is not yet
running. The MultiThreadedExecutor only submits a task to its thread pool, so a task
still waiting in the pool's queue is yielded and submitted again at once, without a
wait: the spinning thread loops at full speed, holds the GIL the pool's workers need to
start, and queues thousands of copies that each do nothing when they run. Measured on
a node receiving 250 kB messages (2 cores): its 5 Hz timer ran 13 times in 10 s, with
gaps of 2.6 s, and 4418 tasks were queued for 74 messages received. rclpy fixed it
after Jazzy (ros2/rclpy#1547, rclpy 10.0.4).

``MultiThreadedExecutor`` here submits a task once until a worker has started it, and
while the only ready work is such a queued task it sleeps briefly instead of spinning,
so the worker gets the GIL.

It also answers a service's refused requests in one turn. rclpy takes one request of a
service per turn of the spinning thread (wait set, hand-over to a worker, the service
back in the wait set), 2.6 ms at the median and 28 ms at the 99th percentile behind a
busy predictor; a burst of 20 requests answered "busy" waited 50-110 ms for its last
one. Here a take that gives a request the service refuses unread (``lean_take.TAKEN``)
is answered at once and the next request taken in the same turn, until one is to be
served or none is left (at most ``DRAIN_LIMIT``). Everything else is rclpy's executor
unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
import threading
import time

from rclpy.executors import (
    ConditionReachedException,
    ExternalShutdownException,
    InvalidHandle,
    ShutdownException,
    TimeoutException,
    await_or_execute,
)
from rclpy.executors import MultiThreadedExecutor as RclpyMultiThreadedExecutor

from vessel_ros_bridge.lean_take import TAKEN

# How long the spinning thread pauses when the only ready work is already queued (s):
# long enough for a waiting worker to take the GIL, short against any callback period.
QUEUED_PAUSE_S = 0.0005
# Refused requests answered in one take at most (about 0.35 ms each): a flood of them
# keeps a worker thread, and the service out of the wait set, for about 50 ms at most.
DRAIN_LIMIT = 128


class MultiThreadedExecutor(RclpyMultiThreadedExecutor):
    """A MultiThreadedExecutor that submits each ready task once (module docstring)."""

    def __init__(self, num_threads: int | None = None, *, context=None) -> None:
        super().__init__(num_threads, context=context)
        self._queued: set = set()
        self._queued_lock = threading.Lock()

    def _run(self, task) -> None:
        # A task that awaits a future is yielded again later: it may then be resubmitted.
        with self._queued_lock:
            self._queued.discard(task)
        task()

    def _take_service(self, srv):
        # rclpy's take of one request, repeated while it gives refused requests (above).
        for _ in range(DRAIN_LIMIT):
            try:
                with srv.handle:
                    request, header = srv.handle.service_take_request(srv.srv_type.Request)
            except InvalidHandle:   # destroyed meanwhile: nothing to do, as in rclpy
                return None
            if header is None:
                return None
            if request is not TAKEN:
                break
            srv.send_response(srv.callback(request, srv.srv_type.Response()), header)
        else:
            return None   # the limit reached: the rest in the next turn

        async def _execute():
            response = await await_or_execute(srv.callback, request, srv.srv_type.Response())
            srv.send_response(response, header)
        return _execute

    def _spin_once_impl(self, timeout_sec: float | None = None,
                        wait_condition: Callable[[], bool] = lambda: False) -> None:
        try:
            handler, _entity, _node = self.wait_for_ready_callbacks(
                timeout_sec, None, wait_condition)
        except (ExternalShutdownException, ShutdownException, TimeoutException,
                ConditionReachedException):
            return
        with self._queued_lock:
            queued = handler in self._queued
            if not queued:
                self._queued.add(handler)
        if queued:
            time.sleep(QUEUED_PAUSE_S)
            return
        self._executor.submit(self._run, handler)
        self._futures.append(handler)
        for future in self._futures[:]:
            if future.done():
                self._futures.remove(future)
                future.result()   # raise any exception of a callback, as rclpy does
