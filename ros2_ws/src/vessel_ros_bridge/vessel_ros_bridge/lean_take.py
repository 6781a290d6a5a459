"""
Taking a request without building it in Python, for an answer that does not read it.

rclpy takes a message in two steps: the middleware's bytes into the type's C struct
(about 0.15 ms for a 145 kB what-if request of 64 plans), then that struct into Python
objects (1.0-1.5 ms more: a ControlPlan, Header and Time object per plan), holding the
interpreter lock. An answer that only says "busy" needs the request's id, not its
contents. ``lean_type(Request)`` is a stand-in class rclpy takes with the type's own
C functions except the conversion to Python, which returns ``TAKEN``.

Both steps are rclpy's (Jazzy, 7.x): its take looks up ``_CREATE_ROS_MESSAGE``,
``_DESTROY_ROS_MESSAGE`` and ``_CONVERT_TO_PY`` on the class's metaclass, a capsule
holding ``PyObject *convert(void *ros_message)``; ``tests/integration/test_lean_take.py``
checks this still holds.
"""

from __future__ import annotations

import ctypes


class Taken:
    """What a lean take gives: a request taken, its contents left unread."""

    __slots__ = ()

    def __repr__(self) -> str:
        return 'TAKEN'


TAKEN = Taken()
_CONVERT = ctypes.CFUNCTYPE(ctypes.py_object, ctypes.c_void_p)
_capsule_new = ctypes.pythonapi.PyCapsule_New
_capsule_new.restype = ctypes.py_object
_capsule_new.argtypes = (ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p)


def _taken(_ros_message) -> Taken:
    return TAKEN


# Module-level: the C function pointer must live as long as any class that holds it.
_TAKEN_CALLBACK = _CONVERT(_taken)
_TAKEN_CAPSULE = _capsule_new(ctypes.cast(_TAKEN_CALLBACK, ctypes.c_void_p), None, None)


def lean_type(message_class: type) -> type:
    """
    Return a stand-in for ``message_class`` whose take gives ``TAKEN``.

    The message is still read whole by the middleware (its sequence number and sender
    stay valid for an answer); only the Python objects are not made.
    """
    from rclpy.type_support import check_for_type_support

    # The capsules are copied now: the type's support must be loaded before, which rclpy
    # otherwise does only when the type is first used (a service made, a message sent).
    check_for_type_support(message_class)
    meta = type(message_class)
    functions = {name: getattr(meta, name) for name in (
        '_CREATE_ROS_MESSAGE', '_DESTROY_ROS_MESSAGE', '_CONVERT_FROM_PY', '_TYPE_SUPPORT')}
    lean_meta = type(f'Lean{meta.__name__}', (type,),
                     {**functions, '_CONVERT_TO_PY': _TAKEN_CAPSULE})
    return lean_meta(f'Lean{message_class.__name__}', (), {'__slots__': ()})


class AdmittingType:
    """
    A service type as an executor sees it, taking requests lean while it admits none.

    ``Request`` is the real class while ``admits()`` is true, the lean stand-in
    otherwise; everything else is the type's. Set as a service's ``srv_type`` after it
    is created: rclpy's executor reads ``srv_type.Request`` at every take.
    """

    def __init__(self, srv_type: type, admits):
        self._srv_type = srv_type
        self._lean = lean_type(srv_type.Request)
        self._admits = admits

    @property
    def Request(self) -> type:   # noqa: N802 - the attribute rclpy reads
        """Return the class the next request is taken as."""
        return self._srv_type.Request if self._admits() else self._lean

    def __getattr__(self, name: str):
        return getattr(self._srv_type, name)
