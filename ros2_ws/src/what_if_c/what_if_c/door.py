"""
The predictor's what-if service in C: admission and "busy" answers off the interpreter.

``open_door(node, name, capacity, longest)`` creates the ``Predict`` service ``name``
on an rclpy node; a thread of the door's own takes every request, admits at most
``capacity`` at a time for the node (``Door.take()``, answered with ``Door.answer``)
and answers the rest "busy" at once with ``retry_after`` (``Hint``: the running
request's expected end for the first refused client, one service time later for each
next, at most ``longest`` s). ``Door.close()`` before the node is destroyed.

``Door.take()`` gives a request as a read-only ``Request`` record (plans,
answer_period), each plan a ``Plan`` record with ControlPlan's fields (its values a
float64 memoryview), read in C: rosidl's Python messages cost 9 ms for 1,000 plans
(``read_request`` gives the same records for a request's CDR bytes, for tests).

A successful answer's Forecasts are best sent as ``Door.answer_batch(token, message,
withheld, batch)``, ``batch`` a ``hybrid_predictor.forecast_messages.ForecastBatch``:
written in C from its arrays, no Python message per forecast (``response_cdr`` gives
the bytes it sends, for tests).
"""

from __future__ import annotations

from what_if_c import _door
from what_if_c._door import MAX_CAPACITY, Door, Hint, Plan, Request, read_request

__all__ = ['MAX_CAPACITY', 'Door', 'Hint', 'Plan', 'Request', 'open_door', 'read_request',
           'response_cdr']


def open_door(node, name: str, capacity: int, longest: float) -> Door:
    """Return a Door serving ``Predict`` as ``name`` (resolved by rcl) on ``node``."""
    from rclpy.type_support import check_for_type_support

    from hybrid_predictor_interfaces.srv import Predict

    # The door answers busy with Predict's own C message: it serves no other type.
    check_for_type_support(Predict)
    _load_forecast_support()
    return Door(node.handle.pointer, node.context.handle.pointer, name, Predict, capacity,
                longest)


def response_cdr(message: str, withheld: list[str], batch) -> bytes:
    """Return the CDR bytes of the successful answer ``Door.answer_batch`` sends for these."""
    _load_forecast_support()
    return _door.response_cdr(message, withheld, batch)


def _load_forecast_support() -> None:
    """Load Forecast's C support: a batch's template is converted by Forecast's own."""
    from rclpy.type_support import check_for_type_support

    from hybrid_predictor_interfaces.msg import Forecast

    check_for_type_support(Forecast)
