"""Zip files broken on purpose, the ways an upload can be: an encrypted member, a
compression method Python cannot read, a corrupt deflate stream."""

from __future__ import annotations

import struct

#: The ways :func:`broken_first_member` breaks a zip.
BREAKS = ("encrypted", "deflate64", "corrupt")


def broken_first_member(data: bytes, how: str) -> bytes:
    """``data`` (a zip whose first member is deflated) with that member broken ``how``:
    ``encrypted`` (its flag set), ``deflate64`` (method 9, which zipfile cannot read) or
    ``corrupt`` (a reserved deflate block type as its first byte)."""
    buf = bytearray(data)
    local, central = buf.find(b"PK\x03\x04"), buf.find(b"PK\x01\x02")
    if how == "encrypted":
        for offset in (local + 6, central + 8):
            struct.pack_into("<H", buf, offset, struct.unpack_from("<H", buf, offset)[0] | 1)
    elif how == "deflate64":
        for offset in (local + 8, central + 10):
            struct.pack_into("<H", buf, offset, 9)
    elif how == "corrupt":
        name_length, extra_length = struct.unpack_from("<HH", buf, local + 26)
        buf[local + 30 + name_length + extra_length] = 0xFF  # BTYPE 11: reserved
    else:
        raise ValueError(f"unknown break {how!r}")
    return bytes(buf)
