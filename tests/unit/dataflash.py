"""
ArduPilot DataFlash records written byte by byte, for logs the tests make.

A log is FMT records (each message type's id, name, format characters and column
names), then messages: the sync bytes 0xA3 0x95, the type's id, its packed fields.
``STRUCT`` maps the format characters the tests use to Python's struct codes.
"""

import struct

STRUCT = {'Q': 'Q', 'I': 'I', 'f': 'f', 'L': 'i', 'H': 'H', 'B': 'B'}
HEAD = b'\xa3\x95'


def fmt_record(msg_id: int, name: str, fmt: str, columns) -> bytes:
    """Return the FMT record that declares a message type."""
    length = 3 + struct.calcsize('<' + ''.join(STRUCT[c] for c in fmt))
    return HEAD + b'\x80' + struct.pack('<BB4s16s64s', msg_id, length, name.encode(),
                                        fmt.encode(), ','.join(columns).encode())


def record(msg_id: int, fmt: str, values) -> bytes:
    """Return one message of a declared type."""
    return HEAD + struct.pack('<B', msg_id) + struct.pack(
        '<' + ''.join(STRUCT[c] for c in fmt), *values)
