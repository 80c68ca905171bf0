"""Edits of real JPEG frames that the geotag tests need, made on the bytes."""

from __future__ import annotations

from acquisition import exif


def without_xmp_padding(data: bytes) -> bytes:
    """``data`` with the whitespace padding of its XMP packet taken out and the XMP segment's
    length field fixed: a frame whose header has no room to grow in place."""
    split = exif._split_bytes(data, "frame")
    end = data.rfind(b"<?xpacket end=", 0, split.sos_offset)
    start = end
    while data[start - 1 : start] in (b" ", b"\n"):
        start -= 1
    segment_at = data.rfind(b"\xff\xe1", 0, end)
    length = int.from_bytes(data[segment_at + 2 : segment_at + 4], "big") - (end - start)
    return data[: segment_at + 2] + length.to_bytes(2, "big") + data[segment_at + 4 : start] + data[end:]
