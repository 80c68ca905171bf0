"""A JPEG header's EXIF (TIFF) and XMP, read and patched in Python: the fast path of :mod:`acquisition.exif`.

exiv2 costs 2-6 ms a frame to open, read and rewrite a header; a survey's frames all have the
same few-KiB structure, so the common case is done here in a fraction of that, and anything this
module does not understand returns None and goes to exiv2 as before.

Reading (:func:`header_maps`): the tags :mod:`acquisition.exif` uses, in pyexiv2's key -> text
form (``"Exif.GPSInfo.GPSLatitude": "41/1 25/1 432518/10000"``), from IFD0, the Exif IFD and the
GPS IFD, the XMP properties of the namespaces it reads (parsed by ElementTree), and the pixel size
from the SOF segment.

Patching (:func:`patch_header`), without moving a single existing byte of the TIFF block, so that
every offset in it (maker notes included, which are full of absolute offsets) stays valid:

- the new GPS IFD and its values are appended at the end of the TIFF block and IFD0's GPSInfo
  entry is pointed at it; when IFD0 has no GPSInfo entry, a copy of IFD0 with one more entry is
  appended too and the TIFF header points at it. The old GPS IFD and its values, and a replaced
  IFD0 directory, are zeroed: the file carries one position, not two;
- XMP properties are changed in the packet's text (attribute or simple element form), declaring
  the namespace when it is new; a header without XMP gets a new packet after its EXIF segment;
- the header keeps its length when the XMP packet's padding (the whitespace the XMP
  specification reserves for edits in place) can absorb the growth: the image data then stays at
  its offset, and the writer copies the whole file in the kernel and writes the header over it.

Every patch is read back with :func:`header_maps` and compared with what was asked (the keys set
have their new text, the keys removed are gone, every other key is unchanged); a mismatch, a
segment that would exceed 64 KiB, several EXIF or XMP segments, or an XMP structure the text
editor does not handle returns None.
"""

from __future__ import annotations

import re
import struct
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from typing import Any

EXIF_ID = b"Exif\x00\x00"
XMP_ID = b"http://ns.adobe.com/xap/1.0/\x00"
_MAX_PAYLOAD = 65533  # a segment's length field counts itself: 65535 - 2

# XMP namespace -> the prefix exiv2 uses in its keys (Xmp.<prefix>.<name>).
XMP_PREFIXES = {
    "http://ns.adobe.com/exif/1.0/": "exif",
    "http://ns.adobe.com/photoshop/1.0/": "photoshop",
    "http://ns.adobe.com/xap/1.0/": "xmp",
    "http://pix4d.com/camera/1.0/": "Camera",
    "http://www.dji.com/drone-dji/1.0/": "drone-dji",
}
_URI_OF_PREFIX = {prefix: uri for uri, prefix in XMP_PREFIXES.items()}
_RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
_XML_LANG = "{http://www.w3.org/XML/1998/namespace}lang"

# (IFD, tag) -> key, for the tags read. Text tags are decoded whatever their stored type (the
# Sequoia stores GPSDateStamp as UNDEFINED; exiv2 decodes it as text too).
_IFD0_TAGS = {0x010F: "Exif.Image.Make", 0x0110: "Exif.Image.Model"}
_EXIF_TAGS = {
    0x829A: "Exif.Photo.ExposureTime",
    0x9003: "Exif.Photo.DateTimeOriginal",
    0x9011: "Exif.Photo.OffsetTimeOriginal",
    0x920A: "Exif.Photo.FocalLength",
    0x9291: "Exif.Photo.SubSecTimeOriginal",
    0xA002: "Exif.Photo.PixelXDimension",
    0xA003: "Exif.Photo.PixelYDimension",
    0xA20E: "Exif.Photo.FocalPlaneXResolution",
    0xA20F: "Exif.Photo.FocalPlaneYResolution",
    0xA210: "Exif.Photo.FocalPlaneResolutionUnit",
    0xA405: "Exif.Photo.FocalLengthIn35mmFilm",
}
GPS_TAGS = {
    0x00: "Exif.GPSInfo.GPSVersionID",
    0x01: "Exif.GPSInfo.GPSLatitudeRef",
    0x02: "Exif.GPSInfo.GPSLatitude",
    0x03: "Exif.GPSInfo.GPSLongitudeRef",
    0x04: "Exif.GPSInfo.GPSLongitude",
    0x05: "Exif.GPSInfo.GPSAltitudeRef",
    0x06: "Exif.GPSInfo.GPSAltitude",
    0x07: "Exif.GPSInfo.GPSTimeStamp",
    0x10: "Exif.GPSInfo.GPSImgDirectionRef",
    0x11: "Exif.GPSInfo.GPSImgDirection",
    0x12: "Exif.GPSInfo.GPSMapDatum",
    0x1D: "Exif.GPSInfo.GPSDateStamp",
}
_TEXT_KEYS = {
    "Exif.Image.Make",
    "Exif.Image.Model",
    "Exif.Photo.DateTimeOriginal",
    "Exif.Photo.OffsetTimeOriginal",
    "Exif.Photo.SubSecTimeOriginal",
    "Exif.GPSInfo.GPSLatitudeRef",
    "Exif.GPSInfo.GPSLongitudeRef",
    "Exif.GPSInfo.GPSImgDirectionRef",
    "Exif.GPSInfo.GPSMapDatum",
    "Exif.GPSInfo.GPSDateStamp",
}
_GPS_TAG_OF = {key: tag for tag, key in GPS_TAGS.items()}
# The TIFF types written for the GPS tags (as exiv2 writes them): 1 BYTE, 2 ASCII, 5 RATIONAL.
_GPS_TYPES = {
    "Exif.GPSInfo.GPSVersionID": 1,
    "Exif.GPSInfo.GPSAltitudeRef": 1,
    "Exif.GPSInfo.GPSLatitude": 5,
    "Exif.GPSInfo.GPSLongitude": 5,
    "Exif.GPSInfo.GPSAltitude": 5,
    "Exif.GPSInfo.GPSTimeStamp": 5,
    "Exif.GPSInfo.GPSImgDirection": 5,
}
_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8}
_SOF = {*range(0xC0, 0xD0)} - {0xC4, 0xC8, 0xCC}


class UnsupportedHeaderError(Exception):
    """The header is outside what this module handles; the caller uses exiv2."""


# --------------------------------------------------------------------------------------------
# Segments


def segments(header: bytes) -> list[tuple[int, int, int]]:
    """(marker, start, end) of each segment of a JPEG header (SOI to just before SOS)."""
    if header[:2] != b"\xff\xd8":
        raise UnsupportedHeaderError("no SOI")
    out: list[tuple[int, int, int]] = []
    pos, size = 2, len(header)
    while pos < size:
        if header[pos] != 0xFF or pos + 4 > size:
            raise UnsupportedHeaderError(f"structure at byte {pos}")
        marker = header[pos + 1]
        if marker == 0xFF or marker == 0x01 or 0xD0 <= marker <= 0xD9:
            raise UnsupportedHeaderError("fill byte or standalone marker in the header")
        end = pos + 2 + int.from_bytes(header[pos + 2 : pos + 4], "big")
        if end > size or end < pos + 4:
            raise UnsupportedHeaderError(f"segment length at byte {pos}")
        out.append((marker, pos, end))
        pos = end
    return out


def _find(header: bytes, segs: list[tuple[int, int, int]], ident: bytes) -> list[tuple[int, int]]:
    return [(s, e) for m, s, e in segs if m == 0xE1 and header[s + 4 : s + 4 + len(ident)] == ident]


# --------------------------------------------------------------------------------------------
# TIFF


#: Compiled struct layouts by format (IFDs of the same length, values of the same count recur
#: from frame to frame); bounded, so that a hostile header cannot grow it without end.
_STRUCTS: dict[str, struct.Struct] = {}


def _layout(fmt: str) -> struct.Struct:
    layout = _STRUCTS.get(fmt)
    if layout is None:
        layout = struct.Struct(fmt)
        if len(_STRUCTS) < 512:
            _STRUCTS[fmt] = layout
    return layout


_NUMBER_CODES = {1: "B", 3: "H", 4: "I", 6: "b", 8: "h", 9: "i"}


class _Tiff:
    def __init__(self, data: bytes) -> None:
        if data[:4] == b"II*\x00":
            self.order = "<"
        elif data[:4] == b"MM\x00*":
            self.order = ">"
        else:
            raise UnsupportedHeaderError("TIFF header")
        self.data = data
        self.ifd0 = self.u32(4)

    def u16(self, at: int) -> int:
        if at + 2 > len(self.data):
            raise UnsupportedHeaderError("offset outside the TIFF block")
        value: int = struct.unpack_from(self.order + "H", self.data, at)[0]
        return value

    def u32(self, at: int) -> int:
        if at + 4 > len(self.data):
            raise UnsupportedHeaderError("offset outside the TIFF block")
        value: int = struct.unpack_from(self.order + "I", self.data, at)[0]
        return value

    def fields(self, at: int) -> tuple[int, ...]:
        """(tag, type, count) of each entry of the IFD at ``at``, flat, in the IFD's order."""
        if at < 8 or at + 2 > len(self.data):
            raise UnsupportedHeaderError("IFD offset")
        n = self.u16(at)
        if at + 2 + 12 * n + 4 > len(self.data):
            raise UnsupportedHeaderError("IFD runs past the TIFF block")
        values: tuple[int, ...] = _layout(self.order + "HHI4x" * n).unpack_from(self.data, at + 2)
        return values

    def entries(self, at: int) -> list[tuple[int, int, int, int]]:
        """(tag, type, count, entry offset) of the IFD at ``at``."""
        fields = self.fields(at)
        return [(fields[k], fields[k + 1], fields[k + 2], at + 2 + 4 * k) for k in range(0, len(fields), 3)]

    def value_span(self, type_: int, count: int, entry: int) -> tuple[int, int]:
        """(offset, length) of an entry's value bytes."""
        size = _TYPE_SIZE.get(type_)
        if size is None:
            raise UnsupportedHeaderError(f"TIFF type {type_}")
        length = size * count
        at = entry + 8 if length <= 4 else self.u32(entry + 8)
        if at + length > len(self.data):
            raise UnsupportedHeaderError("value outside the TIFF block")
        return at, length


def _read_ifd(tiff: _Tiff, at: int, wanted: Mapping[int, str], out: dict[str, str]) -> dict[int, int]:
    """Read the wanted tags of one IFD into ``out``; returns {tag: entry offset} of every tag.

    Text tags are decoded whatever their stored type of 1, 2 or 7 (to the first NUL); numbers as
    exiv2 writes them: integers, 'num/den' rationals, space-separated."""
    where: dict[int, int] = {}
    data, order = tiff.data, tiff.order
    fields = tiff.fields(at)
    first = at + 2
    offset = _layout(order + "I").unpack_from
    for k in range(0, len(fields), 3):
        tag = fields[k]
        entry = first + 4 * k  # the (k / 3)th entry, 12 bytes each
        where[tag] = entry
        key = wanted.get(tag)
        if key is None:
            continue
        type_, count = fields[k + 1], fields[k + 2]
        size = _TYPE_SIZE.get(type_)
        if size is None:
            raise UnsupportedHeaderError(f"TIFF type {type_}")
        length = size * count
        value_at = entry + 8 if length <= 4 else offset(data, entry + 8)[0]  # inside: the IFD fits
        if value_at + length > len(data):
            raise UnsupportedHeaderError("value outside the TIFF block")
        if key in _TEXT_KEYS:
            if type_ not in (1, 2, 7):
                raise UnsupportedHeaderError("text tag of a numeric type")
            out[key] = data[value_at : value_at + length].split(b"\x00", 1)[0].decode("latin-1")
        elif type_ == 5 or type_ == 10:
            values = _layout(f"{order}{2 * count}{'I' if type_ == 5 else 'i'}").unpack_from(data, value_at)
            out[key] = " ".join(map("{}/{}".format, values[0::2], values[1::2]))
        else:
            code = _NUMBER_CODES.get(type_)
            if code is None:
                raise UnsupportedHeaderError(f"numeric tag of type {type_}")
            out[key] = " ".join(map(str, _layout(f"{order}{count}{code}").unpack_from(data, value_at)))
    return where


def _pointer(tiff: _Tiff, where: dict[int, int], tag: int) -> int | None:
    entry = where.get(tag)
    if entry is None:
        return None
    if tiff.u16(entry + 2) not in (4, 13) or tiff.u32(entry + 4) != 1:
        raise UnsupportedHeaderError("sub-IFD pointer type")
    return tiff.u32(entry + 8)


def exif_map(tiff_data: bytes) -> dict[str, str]:
    """The tags :mod:`acquisition.exif` reads from a TIFF block, as pyexiv2's key -> text."""
    tiff = _Tiff(tiff_data)
    out: dict[str, str] = {}
    where0 = _read_ifd(tiff, tiff.ifd0, _IFD0_TAGS, out)
    exif_at = _pointer(tiff, where0, 0x8769)
    if exif_at is not None:
        _read_ifd(tiff, exif_at, _EXIF_TAGS, out)
    gps_at = _pointer(tiff, where0, 0x8825)
    if gps_at is not None:
        _read_ifd(tiff, gps_at, GPS_TAGS, out)
    return out


# --------------------------------------------------------------------------------------------
# XMP


def _packet_text(payload: bytes) -> str:
    return payload[len(XMP_ID) :].decode("utf-8")


def xmp_map(packet: str) -> dict[str, Any]:
    """The simple properties (and the first item of arrays) of the namespaces in XMP_PREFIXES,
    as pyexiv2's key -> text (arrays as lists)."""
    return _parsed_xmp_map(packet.strip().encode("utf-8"))


def payload_xmp_map(payload: bytes) -> dict[str, Any]:
    """:func:`xmp_map` of an APP1 XMP segment's payload (identifier included), parsed from its
    bytes as they stand when that is the same as decoding and encoding them again: the packet
    (stripped of ASCII white space) runs from ``<`` to ``>`` and is not an XML declaration (so
    expat reads it as UTF-8, and rejects what is not UTF-8 where the decoding would). Sparing the
    round trip through a Python string matters: a packet that begins ``<?xpacket begin="\ufeff"``
    decodes to two bytes a character, which cost a fifth of a Sequoia frame's parse."""
    data = payload[len(XMP_ID) :].strip()
    if data[:1] != b"<" or data[-1:] != b">" or data.startswith(b"<?xml"):
        return xmp_map(_packet_text(payload))
    return _parsed_xmp_map(data)


#: Element and attribute names ({uri}local, as ElementTree gives them) -> pyexiv2 key, or None
#: outside the namespaces read: a camera's few dozen names, bounded against a hostile packet.
_KEYS: dict[str, str | None] = {}


def _parsed_xmp_map(data: bytes) -> dict[str, Any]:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as error:
        raise UnsupportedHeaderError(f"XMP: {error}") from None
    out: dict[str, Any] = {}
    keys = _KEYS
    for description in root.iter(f"{{{_RDF}}}Description"):
        for name, value in description.attrib.items():
            key = keys[name] if name in keys else _key_of(name)
            if key is not None:
                _put(out, key, value)
        for child in description:
            key = keys[child.tag] if child.tag in keys else _key_of(child.tag)
            if key is None:
                continue
            if len(child) == 0:
                _put(out, key, child.text or "")
                continue
            container = child[0]
            items = [li.text or "" for li in container if li.tag == f"{{{_RDF}}}li"]
            if container.tag == f"{{{_RDF}}}Alt":
                langs = [li.get(_XML_LANG, "x-default") for li in container if li.tag == f"{{{_RDF}}}li"]
                _put(out, key, {f'lang="{lang}"': text for lang, text in zip(langs, items, strict=True)})
            elif container.tag in (f"{{{_RDF}}}Seq", f"{{{_RDF}}}Bag"):
                _put(out, key, items)
            else:
                _put(out, key, "")  # a structure: present, its text is not read
    return out


def _key_of(name: str) -> str | None:
    key = None
    if name.startswith("{"):
        uri, _, local = name[1:].partition("}")
        prefix = XMP_PREFIXES.get(uri)
        key = None if prefix is None else f"Xmp.{prefix}.{local}"
    if len(_KEYS) < 4096:
        _KEYS[name] = key
    return key


def _put(out: dict[str, Any], key: str, value: Any) -> None:
    if key in out:
        raise UnsupportedHeaderError(f"{key} appears twice in the XMP")
    out[key] = value


# --------------------------------------------------------------------------------------------
# The whole header


def sof_size(header: bytes, segs: list[tuple[int, int, int]]) -> tuple[int | None, int | None]:
    for marker, start, _ in segs:
        if marker in _SOF:
            height, width = struct.unpack_from(">HH", header, start + 5)
            return (width or None), (height or None)
    return None, None


def header_maps(header: bytes) -> tuple[dict[str, str], dict[str, Any], int | None, int | None]:
    """(EXIF map, XMP map, width px, height px) of a JPEG header (everything before SOS).
    Raises :class:`UnsupportedHeaderError` for what exiv2 should read instead."""
    segs = segments(header)
    exifs = _find(header, segs, EXIF_ID)
    xmps = _find(header, segs, XMP_ID)
    if len(exifs) > 1 or len(xmps) > 1:
        raise UnsupportedHeaderError("several EXIF or XMP segments")
    exif = exif_map(header[exifs[0][0] + 4 + len(EXIF_ID) : exifs[0][1]]) if exifs else {}
    xmp = payload_xmp_map(header[xmps[0][0] + 4 : xmps[0][1]]) if xmps else {}
    width, height = sof_size(header, segs)
    return exif, xmp, width, height


def _segment(payload: bytes) -> bytes:
    if len(payload) > _MAX_PAYLOAD:
        raise UnsupportedHeaderError("segment over 64 KiB")
    return b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload


def _rational_pairs(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split():
        num, _, den = part.partition("/")
        out += [int(num), int(den or "1")]
    return out


def _gps_ifd(values: Mapping[str, str], at: int, order: str) -> bytes:
    """A GPS IFD at TIFF offset ``at`` holding ``values`` (key -> exiv2 text), values after it."""
    keys = sorted(values, key=lambda k: _GPS_TAG_OF[k])
    directory_size = 2 + 12 * len(keys) + 4
    entries, data = [], b""
    for key in keys:
        text, type_ = values[key], _GPS_TYPES.get(key, 2)
        if type_ == 1:
            raw = bytes(int(v) for v in text.split())
        elif type_ == 5:
            pairs = _rational_pairs(text)
            raw = struct.pack(f"{order}{len(pairs)}I", *pairs)
        else:
            raw = text.encode("ascii") + b"\x00"
        count = len(raw) // (8 if type_ == 5 else 1)
        if len(raw) <= 4:
            field = raw.ljust(4, b"\x00")
        else:
            field = struct.pack(order + "I", at + directory_size + len(data))
            data += raw + (b"\x00" if len(raw) % 2 else b"")
        entries.append(struct.pack(order + "HHI", _GPS_TAG_OF[key], type_, count) + field)
    return struct.pack(order + "H", len(keys)) + b"".join(entries) + b"\x00\x00\x00\x00" + data


def _zero(block: bytearray, start: int, length: int) -> None:
    block[start : start + length] = bytes(length)


def patch_exif(tiff_data: bytes, gps: Mapping[str, str]) -> bytes:
    """The TIFF block with its GPS IFD replaced by ``gps`` (key -> exiv2 text), nothing moved."""
    tiff = _Tiff(tiff_data)
    order = tiff.order
    block = bytearray(tiff_data)
    if len(block) % 2:
        block += b"\x00"
    entries0 = tiff.entries(tiff.ifd0)
    where0 = {tag: entry for tag, _, _, entry in entries0}
    old_gps = _pointer(tiff, where0, 0x8825)
    if old_gps is not None:
        # Zero the old fix: its directory and its out-of-line values.
        for _, type_, count, entry in tiff.entries(old_gps):
            at, length = tiff.value_span(type_, count, entry)
            if at != entry + 8:
                _zero(block, at, length)
        _zero(block, old_gps, 2 + 12 * len(tiff.entries(old_gps)) + 4)
    if 0x8825 in where0:
        gps_at = len(block)
        block[where0[0x8825] + 8 : where0[0x8825] + 12] = struct.pack(order + "I", gps_at)
        block += _gps_ifd(gps, gps_at, order)
        return bytes(block)
    # No GPSInfo entry: a new IFD0 with one, appended, and the header pointed at it.
    n = len(entries0)
    ifd0_at = len(block)
    gps_at = ifd0_at + 2 + 12 * (n + 1) + 4
    rows = [tiff_data[e : e + 12] for _, _, _, e in entries0]
    rows.append(struct.pack(order + "HHII", 0x8825, 4, 1, gps_at))
    rows.sort(key=lambda row: struct.unpack_from(order + "H", row)[0])
    next_ifd = tiff.u32(tiff.ifd0 + 2 + 12 * n)
    new_ifd0 = struct.pack(order + "H", n + 1) + b"".join(rows) + struct.pack(order + "I", next_ifd)
    _zero(block, tiff.ifd0, 2 + 12 * n + 4)
    block[4:8] = struct.pack(order + "I", ifd0_at)
    block += new_ifd0 + _gps_ifd(gps, gps_at, order)
    return bytes(block)


_ESCAPES = {"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;"}


def _escape(text: str) -> str:
    return "".join(_ESCAPES.get(c, c) for c in text)


_NAMESPACE_DECLARATION = re.compile(r"xmlns:([\w.-]+)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")


_NAME_CHAR = re.compile(r"[\w.:-]")
_ATTRIBUTE_VALUE = re.compile(r"\s*=\s*(?:\"[^\"]*\"|'[^']*')\s?")
_ELEMENT_VALUE = re.compile(r">([^<]*)</")


def _replace_property(packet: str, name: str, value: str | None, key: str) -> str:
    """Set (or, for None, remove) the one simple property ``name`` (prefix:local) of the packet."""
    found: list[tuple[int, int, str]] = []  # (start, end, form)
    at = packet.find(name)
    while at >= 0:
        after = at + len(name)
        before_char = packet[at - 1] if at > 0 else ""
        if after < len(packet) and _NAME_CHAR.match(packet, after) is None:
            if before_char.isspace():
                match = _ATTRIBUTE_VALUE.match(packet, after)
                if match is not None:
                    found.append((at, match.end(), "attribute"))
            elif before_char == "<":
                match = _ELEMENT_VALUE.match(packet, after)
                closing = f"</{name}>"
                if match is None or not packet.startswith(closing, match.end() - 2):
                    raise UnsupportedHeaderError(f"{key} is not a simple property")
                found.append((at - 1, match.end() - 2 + len(closing), "element"))
        at = packet.find(name, after)
    if len(found) != 1:
        raise UnsupportedHeaderError(f"{key} appears {len(found)} times")
    start, end, form = found[0]
    if value is None:
        new = ""
    elif form == "attribute":
        new = f'{name}="{_escape(value)}" '
    else:
        new = f"<{name}>{_escape(value)}</{name}>"
    return packet[:start] + new + packet[end:]


def patch_xmp(packet: str, changes: Mapping[str, str | None]) -> str:
    """The XMP packet with ``changes`` (key -> new text, None: remove) made in its text."""
    prefixes: dict[str, set[str]] = {}
    for prefix, uri_double, uri_single in _NAMESPACE_DECLARATION.findall(packet):
        prefixes.setdefault(uri_double or uri_single, set()).add(prefix)
    for key, value in changes.items():
        _, prefix_key, local = key.split(".", 2)
        uri = _URI_OF_PREFIX[prefix_key]
        declared = prefixes.get(uri, set())
        if len(declared) > 1:
            raise UnsupportedHeaderError(f"{uri} bound to several prefixes")
        prefix = next(iter(declared), None)
        if prefix is not None and f"{prefix}:{local}" in packet:
            packet = _replace_property(packet, f"{prefix}:{local}", value, key)
            continue
        if value is None:
            continue
        # A new property: an attribute of the first rdf:Description (declaring the namespace).
        match = re.search(r"<rdf:Description\b[^>]*?(/?)>", packet)
        if match is None:
            raise UnsupportedHeaderError("no rdf:Description with the rdf prefix")
        add = f' {prefix or prefix_key}:{local}="{_escape(value)}"'
        if prefix is None:
            if prefix_key in {p for ps in prefixes.values() for p in ps}:
                raise UnsupportedHeaderError(f"prefix {prefix_key} bound to another namespace")
            add = f' xmlns:{prefix_key}="{uri}"' + add
            prefixes[uri] = {prefix_key}
        at = match.end() - 1 - len(match.group(1))
        packet = packet[:at] + add + packet[at:]
    return packet


_NEW_PACKET = (
    '<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>'
    '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
    '<rdf:Description rdf:about=""></rdf:Description></rdf:RDF></x:xmpmeta><?xpacket end="w"?>'
)


_WHITESPACE = b" \t\r\n"


def _padded(segment: bytes, growth: int) -> bytes:
    """An XMP segment with ``growth`` bytes taken out of (or, when negative, added to) the
    packet's padding, the whitespace before ``<?xpacket end=...?>`` that the XMP specification
    reserves for edits in place; the segment unchanged when its padding is too short."""
    end = segment.rfind(b"<?xpacket end=")
    start = max(4, len(segment[:end].rstrip(_WHITESPACE)))
    if growth == 0 or end < 0 or end - start < growth:
        return segment
    if growth > 0:
        return _segment(segment[4 : end - growth] + segment[end:])
    return _segment(segment[4:end] + b" " * -growth + segment[end:])


def patch_header(
    header: bytes,
    gps: Mapping[str, str],
    xmp_changes_for: Callable[[dict[str, Any]], Mapping[str, str | None]],
    *,
    maps: tuple[dict[str, str], dict[str, Any]] | None = None,
) -> bytes:
    """The header with its GPS IFD replaced by ``gps`` and the XMP changes made that
    ``xmp_changes_for(the header's XMP map)`` asks for (key -> text, None: remove), checked by
    reading it back. ``maps``: the header's (EXIF, XMP) maps from :func:`header_maps` when the
    caller has them already. Raises :class:`UnsupportedHeaderError` when exiv2 should do it
    instead."""
    segs = segments(header)
    exifs = _find(header, segs, EXIF_ID)
    xmps = _find(header, segs, XMP_ID)
    if len(exifs) != 1 or len(xmps) > 1:
        raise UnsupportedHeaderError("no EXIF segment, or several EXIF or XMP segments")
    if maps is None:
        old_exif, old_xmp, _, _ = header_maps(header)
    else:
        old_exif, old_xmp = maps
    (e_start, e_end) = exifs[0]
    new_tiff = patch_exif(header[e_start + 4 + len(EXIF_ID) : e_end], gps)
    pieces: list[tuple[int, int, bytes]] = [(e_start, e_end, _segment(EXIF_ID + new_tiff))]
    xmp_changes = {k: v for k, v in xmp_changes_for(old_xmp).items() if v is not None or k in old_xmp}
    if xmp_changes:
        if xmps:
            x_start, x_end = xmps[0]
            packet = patch_xmp(_packet_text(header[x_start + 4 : x_end]), xmp_changes)
            pieces.append((x_start, x_end, _segment(XMP_ID + packet.encode("utf-8"))))
        else:
            packet = patch_xmp(_NEW_PACKET, xmp_changes)
            pieces.append((e_end, e_end, _segment(XMP_ID + packet.encode("utf-8"))))
    if xmps:
        # The XMP padding absorbs the growth, so that the image data stays where it was.
        if not xmp_changes:
            pieces.append((xmps[0][0], xmps[0][1], header[xmps[0][0] : xmps[0][1]]))
        growth = sum(len(data) - (end - start) for start, end, data in pieces)
        x_start, x_end, data = pieces[-1]
        pieces[-1] = (x_start, x_end, _padded(data, growth))
    out, pos = [], 0
    for start, end, data in sorted(pieces, key=lambda p: (p[0], p[1])):
        out += [header[pos:start], data]
        pos = end
    out.append(header[pos:])
    new_header = b"".join(out)
    # Read back: what was asked is there, and nothing else changed. Only the new segments are
    # parsed (what header_maps would find in the new header: every other segment is the old one).
    new_exif = exif_map(pieces[0][2][4 + len(EXIF_ID) :])
    new_xmp = payload_xmp_map(pieces[-1][2][4:]) if len(pieces) > 1 else {}
    want_exif = {k: v for k, v in old_exif.items() if not k.startswith("Exif.GPSInfo.")} | dict(gps)
    want_xmp = {k: v for k, v in ({**old_xmp, **xmp_changes}).items() if v is not None}
    if new_exif != want_exif or new_xmp != want_xmp:
        raise UnsupportedHeaderError("read-back differs from the request")
    return new_header
