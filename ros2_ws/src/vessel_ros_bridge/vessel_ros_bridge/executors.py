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
so the worker gets the GIL. Everything else is rclpy's executor unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
import threading
import time

from rclpy.executors import (
    ConditionReachedException,
    ExternalShutdownException,
    ShutdownException,
    TimeoutException,
)
from rclpy.executors import MultiThreadedExecutor as RclpyMultiThreadedExecutor

# How long the spinning thread pauses when the only ready work is already queued (s):
# long enough for a waiting worker to take the GIL, short against any callback period.
QUEUED_PAUSE_S = 0.0005


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
