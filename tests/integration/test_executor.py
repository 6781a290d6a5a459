"""
The nodes' MultiThreadedExecutor submits every ready task once (ros2/rclpy#1452).

rclpy 7.1's executor yields a task again while it waits in the thread pool's queue and
submits it again at once, in a loop that holds the GIL; this one must not. The verdict
counts submissions, it reads no clock.
"""

import threading
import time
import warnings

import pytest

pytestmark = pytest.mark.ros

BUSY_S = 0.05   # each callback keeps the only worker busy this long
RUN_S = 1.5


def test_a_task_waiting_for_a_worker_is_submitted_once():
    import rclpy
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    from vessel_ros_bridge.executors import MultiThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('executor_once', context=context)
    ran = {'a': 0, 'b': 0}

    def busy(name):
        ran[name] += 1
        time.sleep(BUSY_S)

    # Two timers in groups of their own and one worker: whenever one runs, the other's
    # task is ready and waits in the pool's queue.
    for name in ran:
        node.create_timer(BUSY_S / 2, lambda name=name: busy(name),
                          callback_group=MutuallyExclusiveCallbackGroup())
    with warnings.catch_warnings():   # one worker on purpose: rclpy warns about it
        warnings.simplefilter('ignore', UserWarning)
        executor = MultiThreadedExecutor(num_threads=1, context=context)
    submitted, queued, twice = [], set(), []
    lock = threading.Lock()
    pool_submit = executor._executor.submit

    def counting_submit(fn, task, *args):
        with lock:
            if task in queued:
                twice.append(task)
            queued.add(task)
            submitted.append(task)

        def run():
            with lock:
                queued.discard(task)
            fn(task, *args)
        return pool_submit(run)

    executor._executor.submit = counting_submit
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    time.sleep(RUN_S)
    executor.shutdown(timeout_sec=5)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    assert ran['a'] >= 3 and ran['b'] >= 3, ran    # both kept being served
    assert not twice, f'{len(twice)} of {len(submitted)} submissions were of a queued task'
    # Every submission ran a callback (the stock executor queues thousands that do not).
    assert len(submitted) <= ran['a'] + ran['b'] + 2, (len(submitted), ran)
