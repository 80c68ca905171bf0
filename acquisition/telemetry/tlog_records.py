"""The records of a regular .tlog, found without pymavlink's byte-by-byte stream parser.

A .tlog record is 8 bytes of receive time (big-endian microseconds since the Unix epoch) and
one MAVLink frame: v1 (magic 0xFE, 6-byte header) or v2 (0xFD, 10-byte header), its payload
and a 2-byte CRC (CRC-16/MCRF4XX over the frame after the magic, then the message's
CRC_EXTRA byte; the MAVLink serialization spec). pymavlink's log reader decodes every message
of the file to hand it over; the reader (:mod:`acquisition.telemetry.tlog`) wants about one in
seven. :func:`records` walks the records, checks each frame's CRC as pymavlink does, and leaves
the decoding of the ones that are wanted to pymavlink.

It reads only what pymavlink reads the same way: it raises :class:`IrregularLogError` at the first
thing for which pymavlink's robust parsing could do otherwise (a byte that is no magic, a bad
CRC, a signed frame or unknown incompat flags, a record cut short at the end, a frame shorter
than 12 bytes, which pymavlink's reader may read past), and the caller then reads the whole
file with pymavlink instead. On every other file the two give the same messages, with the
same receive times (``tusec * 1.0e-6``, pymavlink's own expression) and file positions.
"""

from __future__ import annotations

import mmap
from collections.abc import Callable, Iterator, Mapping

_V1, _V2 = 0xFE, 0xFD
_SHORTEST = 12  # pymavlink's reader asks for 12 bytes after a v2 frame: a shorter one is read past


class IrregularLogError(Exception):
    """The file holds something for which pymavlink's own parser is the reference."""


#: (receive time s, frame start, frame end, message id, source system, source component)
Record = tuple[float, int, int, int, int, int]


def records(
    data: bytes | mmap.mmap,
    crc_extra: Mapping[int, int],
    crc16: Callable[[bytes, int], int],
) -> Iterator[Record]:
    """The records of ``data`` (a whole .tlog, its bytes or mapped), in file order.
    ``crc_extra``: message id -> CRC_EXTRA of the dialect pymavlink reads the file with; a
    message it does not know is yielded unchecked, as pymavlink hands it over (as an unknown
    message, its CRC unchecked).
    ``crc16(data, initial)``: CRC-16/MCRF4XX. Raises :class:`IrregularLogError`, naming the byte."""
    pos, size = 0, len(data)
    while pos < size:
        start = pos + 8
        if start + 3 > size:
            raise IrregularLogError(f"a record cut short at byte {pos}")
        magic, length = data[start], data[start + 1]
        if magic == _V2:
            if data[start + 2]:
                raise IrregularLogError(f"a signed frame or incompat flags at byte {start}")
            if start + 10 > size:
                raise IrregularLogError(f"a record cut short at byte {pos}")
            msg_id = data[start + 7] | data[start + 8] << 8 | data[start + 9] << 16
            system, component = data[start + 5], data[start + 6]
            end = start + 12 + length
        elif magic == _V1:
            if start + 6 > size:
                raise IrregularLogError(f"a record cut short at byte {pos}")
            msg_id, system, component = data[start + 5], data[start + 3], data[start + 4]
            end = start + 8 + length
        else:
            raise IrregularLogError(f"no MAVLink magic at byte {start}")
        if end > size:
            raise IrregularLogError(f"a record cut short at byte {pos}")
        if end - start < _SHORTEST:
            raise IrregularLogError(f"a {end - start}-byte frame at byte {start}")
        extra = crc_extra.get(msg_id)
        if extra is not None:
            crc = crc16(data[start + 1 : end - 2], 0xFFFF)
            if crc16(bytes((extra,)), crc) != data[end - 2] | data[end - 1] << 8:
                raise IrregularLogError(f"a bad CRC at byte {start}")
        yield int.from_bytes(data[pos:start], "big") * 1.0e-6, start, end, msg_id, system, component
        pos = end
