"""
Field paths into ROS messages: check them against a message type, read them fast.

A path is dotted attribute names, each optionally indexed: ``twist.twist.linear.x``,
``position[2]`` (a fixed index) or ``velocity[propeller]`` (the element at the index
of ``'propeller'`` in the ``name`` list beside the field, as in sensor_msgs/JointState).
Types are checked against a rosbags typestore's field definitions, so a wrong path is
reported before any message is read.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import math
from operator import attrgetter
import re
from typing import Any

import numpy as np
from rosbags.typesys.store import Nodetype

NUMERIC = frozenset({'bool', 'byte', 'char', 'int8', 'int16', 'int32', 'int64', 'uint8',
                     'uint16', 'uint32', 'uint64', 'float32', 'float64'})
NAME_LIST = 'name'  # the sibling list that string indices look up
_SEGMENT = re.compile(r'^([A-Za-z_]\w*)(?:\[([^\[\]]+)\])?$')


class FieldError(ValueError):
    """A field path does not exist in a message type or is not a number."""


@dataclass(frozen=True)
class Segment:
    """One step of a path: an attribute, optionally indexed by position or by name."""

    attr: str
    key: int | str | None = None


def parse_path(path: str) -> tuple[Segment, ...]:
    """Split a field path into segments; raise FieldError if malformed."""
    if not path:
        return ()
    out = []
    for part in path.split('.'):
        match = _SEGMENT.match(part)
        if not match:
            raise FieldError(f'malformed field path {path!r} at {part!r}')
        attr, key = match.groups()
        if key is not None:
            key = key.strip().strip('\'"')
            key = int(key) if re.fullmatch(r'-?\d+', key) else key
        out.append(Segment(attr, key))
    return tuple(out)


def check_path(fielddefs: dict, msgtype: str, path: str) -> None:
    """Raise FieldError unless ``path`` leads to a number in messages of ``msgtype``."""
    current = msgtype
    where = ''
    desc = None
    for seg in parse_path(path):
        if current is None:
            raise FieldError(f'{where} is a number and has no field {seg.attr!r}')
        fields = dict(fielddefs[current][1])
        if seg.attr not in fields:
            raise FieldError(f'no field {seg.attr!r} in {current}')
        desc = fields[seg.attr]
        where = f'{where}.{seg.attr}' if where else seg.attr
        if seg.key is not None:
            if desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                raise FieldError(f'{where} is not an array and cannot be indexed')
            if isinstance(seg.key, str):
                names = fields.get(NAME_LIST)
                if not (names and names[0] == Nodetype.SEQUENCE
                        and names[1][0] == (Nodetype.BASE, ('string', 0))):
                    raise FieldError(f'{where}[{seg.key}] needs a {NAME_LIST!r} string '
                                     f'list beside {seg.attr!r} in {current}')
            desc = desc[1][0]
        current = desc[1] if desc[0] == Nodetype.NAME else None
    if desc is None or desc[0] != Nodetype.BASE or desc[1][0] not in NUMERIC:
        kind = current if current else _describe(desc)
        raise FieldError(f'{path or "(message)"} is {kind}, not a number')


def _describe(desc) -> str:
    if desc is None:
        return 'the whole message'
    if desc[0] == Nodetype.BASE:
        return f'a {desc[1][0]}'
    if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return 'an array (index it)'
    return str(desc[1])


def numeric_paths(fielddefs: dict, msgtype: str, prefix: str = '') -> list[str]:
    """Every numeric leaf path of a message type; arrays are shown as ``name[]``."""
    out = []
    for name, desc in fielddefs[msgtype][1]:
        path = f'{prefix}{name}'
        if desc[0] == Nodetype.NAME:
            out += numeric_paths(fielddefs, desc[1], path + '.')
        elif desc[0] == Nodetype.BASE:
            if desc[1][0] in NUMERIC:
                out.append(path)
        else:
            inner = desc[1][0]
            if inner[0] == Nodetype.BASE and inner[1][0] in NUMERIC:
                out.append(path + '[]')
            elif inner[0] == Nodetype.NAME:
                out += numeric_paths(fielddefs, inner[1], path + '[].')
    return out


def has_header_stamp(fielddefs: dict, msgtype: str) -> bool:
    """Whether the type has ``header.stamp`` (std_msgs/Header) to time its samples."""
    fields = dict(fielddefs[msgtype][1])
    header = fields.get('header')
    return bool(header and header == (Nodetype.NAME, 'std_msgs/msg/Header'))


def compile_getter(path: str, absent: Any = math.nan) -> Callable[[Any], Any]:
    """
    Make a function reading ``path`` from a message; ``absent`` if an index is absent.

    Plain dotted paths become one ``operator.attrgetter`` (the fast, common case).
    """
    segments = parse_path(path)
    if all(seg.key is None for seg in segments):
        return attrgetter(path)

    def get(msg):
        obj = msg
        try:
            for seg in segments:
                parent, obj = obj, getattr(obj, seg.attr)
                if isinstance(seg.key, int):
                    obj = obj[seg.key]
                elif seg.key is not None:
                    obj = obj[getattr(parent, NAME_LIST).index(seg.key)]
        except (IndexError, ValueError):  # element absent from this message
            return absent
        return obj

    return get


def set_path(msg, path: str, value: float) -> None:
    """
    Write ``value`` at ``path`` of a message (the inverse of ``compile_getter``).

    An element indexed by name (``velocity[propeller]``) goes to that name's place in the
    ``name`` list beside the field, appending the name where it is missing; arrays grow
    with zeros to the index they need (and stay numpy arrays where they were).
    """
    segments = parse_path(path)
    obj = msg
    for i, seg in enumerate(segments):
        last = i == len(segments) - 1
        if seg.key is None:
            if last:
                setattr(obj, seg.attr, value)
            else:
                obj = getattr(obj, seg.attr)
            continue
        if isinstance(seg.key, str):
            names = list(getattr(obj, NAME_LIST))
            if seg.key not in names:
                names.append(seg.key)
                setattr(obj, NAME_LIST, names)
            index = names.index(seg.key)
        else:
            index = seg.key
        old = getattr(obj, seg.attr)
        if not last:
            obj = old[index]
            continue
        array = list(old)
        array += [0.0] * (index + 1 - len(array))
        array[index] = value
        setattr(obj, seg.attr, np.asarray(array, float) if isinstance(old, np.ndarray)
                else array)


def pad_named(msg, path: str) -> None:
    """Grow the array a by-name ``path`` ends in to the length of its ``name`` list."""
    *parents, last = parse_path(path)
    if not isinstance(last.key, str) or any(seg.key is not None for seg in parents):
        return
    obj = msg
    for seg in parents:
        obj = getattr(obj, seg.attr)
    old = getattr(obj, last.attr)
    missing = len(getattr(obj, NAME_LIST)) - len(old)
    if missing > 0:
        array = list(old) + [0.0] * missing
        setattr(obj, last.attr, np.asarray(array, float) if isinstance(old, np.ndarray)
                else array)


def stamp_ns(msg) -> int:
    """Header stamp of a message in integer nanoseconds."""
    stamp = msg.header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec
