"""
Read a few numeric fields of many same-shaped CDR messages at once, without a parser.

Deserializing every message in Python is the converter's bottleneck, yet a topic's
messages nearly always share one byte layout: the same frame ids, joint names and
array lengths, so every number sits at the same offset. This module learns that layout
from rosbags itself -- it deserializes one message, gives every number in it a unique
marker value, serializes it again with rosbags and finds the markers -- and then reads
the wanted fields of a whole batch with numpy. A message is read this way only if all
its other bytes (encapsulation header, string lengths and contents, sequence lengths,
padding) equal the template's, which proves it has the same layout; any other message
goes through rosbags' deserializer as usual. The results are bit-identical.
"""

from __future__ import annotations

from collections.abc import Sequence
import copy
from dataclasses import dataclass
import struct

import numpy as np
from rosbags.typesys.store import Nodetype

from .fields import NAME_LIST, parse_path

# Numbers this module can locate by a unique marker, and their little-endian dtypes
# (CDR as ROS 2 writes it on every supported platform is little-endian; a big-endian
# message differs in its header bytes and takes the slow path).
DTYPES = {'float64': '<f8', 'float32': '<f4', 'int64': '<i8', 'uint64': '<u8',
          'int32': '<i4', 'uint32': '<u4'}
_MARK = b'\xa7\x5c'  # in every marker, so markers never look like ordinary data


@dataclass(frozen=True)
class Layout:
    """Where the wanted numbers sit in messages of one byte length."""

    length: int
    template: np.ndarray      # uint8 bytes of the message the layout was learnt from
    fixed: np.ndarray         # indices of bytes every same-layout message shares
    fields: tuple[tuple[int, str], ...]  # (offset, dtype) of each wanted path, in order


def learn(raw: bytes, msgtype: str, paths: Sequence[str], store) -> Layout | None:
    """
    Learn the layout of ``raw`` for the numeric ``paths``; None if it cannot be used.

    ``paths`` may use name indices (``velocity[propeller]``); they are resolved in this
    message, and the name list is part of the fixed bytes, so a reordered list does
    not match.
    """
    msg = store.deserialize_cdr(raw, msgtype)
    if bytes(store.serialize_cdr(msg, msgtype)) != bytes(raw):
        return None  # e.g. non-zero padding: re-serializing would not reproduce it
    marked = copy.deepcopy(msg)
    slots = {}
    for n, (path, owner, key, base) in enumerate(_slots(marked, msgtype, store.fielddefs)):
        if base not in DTYPES:
            continue  # 1- and 2-byte numbers stay among the fixed bytes
        value = _marker(n, base)
        if isinstance(key, int):
            owner[key] = value
        else:
            setattr(owner, key, value)
        slots[path] = (np.dtype(DTYPES[base]).type(value).tobytes(), DTYPES[base])
    out = bytes(store.serialize_cdr(marked, msgtype))
    if len(out) != len(raw):
        return None
    is_value = np.zeros(len(raw), dtype=bool)
    offsets = {}
    for path, (pattern, dtype) in slots.items():
        at = out.find(pattern)
        if at < 0 or out.find(pattern, at + 1) >= 0:
            continue  # not locatable: its bytes stay fixed (stricter, still correct)
        offsets[path] = (at, dtype)
        is_value[at:at + len(pattern)] = True
    fields = []
    for path in paths:
        concrete = _resolve(msg, path)
        if concrete not in offsets:
            return None
        fields.append(offsets[concrete])
    template = np.frombuffer(bytes(raw), dtype=np.uint8)
    return Layout(len(raw), template, np.flatnonzero(~is_value), tuple(fields))


def read(layout: Layout, raws: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """
    Read the layout's fields from messages of its length.

    Returns a boolean mask of the messages that match the layout and, for those, a
    float64 array (n_matching, n_fields).
    """
    block = np.frombuffer(b''.join(raws), dtype=np.uint8).reshape(len(raws), layout.length)
    match = (block[:, layout.fixed] == layout.template[layout.fixed]).all(axis=1)
    rows = block[match]
    values = np.empty((len(rows), len(layout.fields)))
    for k, (offset, dtype) in enumerate(layout.fields):
        size = np.dtype(dtype).itemsize
        values[:, k] = np.ascontiguousarray(rows[:, offset:offset + size]).view(dtype)[:, 0]
    return match, values


def _marker(n: int, base: str):
    """Return a finite value of type ``base`` whose bytes are unique to slot ``n``."""
    size = np.dtype(DTYPES[base]).itemsize
    ident = n.to_bytes(3, 'little')
    if base == 'float64':  # exponent byte 0x40: a finite number between 2 and 4
        return struct.unpack('<d', _MARK + ident + b'\x00\x01\x40')[0]
    if base == 'float32':  # 3 bytes of identity cannot hold the mark as well
        return struct.unpack('<f', ident + b'\x40')[0]
    raw = (_MARK + ident + b'\x00\x00\x00')[:size - 1] + b'\x3a'
    return int(np.frombuffer(raw, dtype=DTYPES[base])[0])


def _slots(obj, msgtype: str, fielddefs: dict, prefix: str = ''):
    """Yield (path, owner, attribute or index, base type) of every number in a message."""
    for name, desc in fielddefs[msgtype][1]:
        kind, detail = desc
        path = prefix + name
        if kind == Nodetype.BASE:
            yield path, obj, name, detail[0]
        elif kind == Nodetype.NAME:
            yield from _slots(getattr(obj, name), detail, fielddefs, path + '.')
        else:
            inner_kind, inner = detail[0]
            items = getattr(obj, name)
            for i in range(len(items)):
                if inner_kind == Nodetype.BASE:
                    yield f'{path}[{i}]', items, i, inner[0]
                elif inner_kind == Nodetype.NAME:
                    yield from _slots(items[i], inner, fielddefs, f'{path}[{i}].')


def _resolve(msg, path: str) -> str | None:
    """Write ``path`` with numeric indices only, resolving names in this message."""
    parts, obj = [], msg
    for seg in parse_path(path):
        parent, obj = obj, getattr(obj, seg.attr)
        if seg.key is None:
            parts.append(seg.attr)
            continue
        if isinstance(seg.key, int):
            index = seg.key
        else:
            names = list(getattr(parent, NAME_LIST))
            if seg.key not in names:
                return None
            index = names.index(seg.key)
        if not 0 <= index < len(obj):
            return None
        obj = obj[index]
        parts.append(f'{seg.attr}[{index}]')
    return '.'.join(parts)
