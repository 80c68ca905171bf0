"""Write tests/data/px4_survey.ulg: a small, genuine PX4 ULog file with a known truth.

There is no real .ulg in ../shared/data, so this script writes one from the ULog file format
specification (PX4 docs, "ULog File Format"): the 16-byte header (magic ``ULog\\x01\\x12\\x35``,
version, start timestamp), a flag-bits message, format ('F'), info ('I') and subscription
('A') messages, then data ('D') and logged-string ('L') messages in time order, every message
framed as uint16 size + uint8 type, little-endian. The test suite reads it with pyulog and
with sfap's reader and compares with :data:`TRUTH`.

The flight (boot clock in seconds ``t``, microseconds in the file):

- UTC = ``UTC0_S + RATE * t`` (a flight-controller crystal running 20 ppm slow);
- vehicle_gps_position at 5 Hz (t = 5.0 .. 65.0) with ``time_utc_usec`` from that line;
- vehicle_global_position at 10 Hz: latitude 47 + 1e-5 * (t - 5) deg, longitude 8 deg,
  altitude 500 + 0.5 * (t - 5) m AMSL;
- vehicle_attitude at 10 Hz: roll 5 sin(t / 3) deg, pitch -2 deg, yaw 30 + t deg;
- camera_trigger and camera_capture every 2 s from t = 10.0 to 60.0 (seq 0 .. 25); capture
  seq 7 reports a failed capture (result 0).

Run ``python tests/data/make_ulog_fixture.py`` to rewrite the file; the output is
deterministic (a test checks that the committed file equals what this script builds).
"""

from __future__ import annotations

import math
import struct
import sys
from pathlib import Path
from typing import Any

UTC0_S = 1_700_000_000.0  # UTC at boot, 2023-11-14T22:13:20Z
RATE = 1.0 + 20e-6
TRIGGER_TIMES_S = [10.0 + 2.0 * k for k in range(26)]
FAILED_SEQ = 7

TRUTH = {
    "utc0_s": UTC0_S,
    "rate": RATE,
    "trigger_times_s": TRIGGER_TIMES_S,
    "failed_seq": FAILED_SEQ,
}

FORMATS = {
    "vehicle_gps_position": [
        ("uint64_t", "timestamp"),
        ("uint64_t", "time_utc_usec"),
        ("int32_t", "lat"),
        ("int32_t", "lon"),
        ("int32_t", "alt"),
        ("uint8_t", "fix_type"),
        ("uint8_t[7]", "_padding0"),
    ],
    "vehicle_global_position": [
        ("uint64_t", "timestamp"),
        ("double", "lat"),
        ("double", "lon"),
        ("float", "alt"),
        ("uint8_t[4]", "_padding0"),
    ],
    "vehicle_attitude": [
        ("uint64_t", "timestamp"),
        ("float[4]", "q"),
    ],
    "camera_trigger": [
        ("uint64_t", "timestamp"),
        ("uint64_t", "timestamp_utc"),
        ("uint32_t", "seq"),
        ("bool", "feedback"),
        ("uint8_t[3]", "_padding0"),
    ],
    "camera_capture": [
        ("uint64_t", "timestamp"),
        ("uint64_t", "timestamp_utc"),
        ("double", "lat"),
        ("double", "lon"),
        ("float", "alt"),
        ("float", "ground_distance"),
        ("float[4]", "q"),
        ("uint32_t", "seq"),
        ("int8_t", "result"),
        ("uint8_t[3]", "_padding0"),
    ],
}

#: vehicle_status as PX4 logs it (the fields sfap reads), written only when asked for.
VEHICLE_STATUS = [
    ("uint64_t", "timestamp"),
    ("uint8_t", "vehicle_type"),
    ("bool", "is_vtol"),
    ("uint8_t", "system_type"),
    ("uint8_t[5]", "_padding0"),
]

_STRUCT = {
    "uint64_t": "Q",
    "int32_t": "i",
    "uint32_t": "I",
    "uint8_t": "B",
    "int8_t": "b",
    "double": "d",
    "float": "f",
    "bool": "?",
}


def utc_s(t: float) -> float:
    return UTC0_S + RATE * t


def position(t: float) -> tuple[float, float, float]:
    return 47.0 + 1e-5 * (t - 5.0), 8.0, 500.0 + 0.5 * (t - 5.0)


def euler_deg(t: float) -> tuple[float, float, float]:
    return 5.0 * math.sin(t / 3.0), -2.0, (30.0 + t) % 360.0


def quaternion(roll_deg: float, pitch_deg: float, yaw_deg: float) -> tuple[float, ...]:
    """(w, x, y, z) of the z-y'-x'' rotation (yaw, pitch, roll), body to NED."""
    cr, sr = math.cos(math.radians(roll_deg) / 2), math.sin(math.radians(roll_deg) / 2)
    cp, sp = math.cos(math.radians(pitch_deg) / 2), math.sin(math.radians(pitch_deg) / 2)
    cy, sy = math.cos(math.radians(yaw_deg) / 2), math.sin(math.radians(yaw_deg) / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def _struct_of(fields: list[tuple[str, str]]) -> str:
    out = "<"
    for ftype, _ in fields:
        if "[" in ftype:
            base, n = ftype[:-1].split("[")
            out += n + _STRUCT[base]
        else:
            out += _STRUCT[ftype]
    return out


def _msg(msg_type: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), msg_type[0]) + payload


def _pack(fields: list[tuple[str, str]], values: dict[str, Any]) -> bytes:
    # PX4's logger leaves the trailing padding of a message out of the data it writes
    # (the format keeps it), and pyulog rejects data longer than the fields without it.
    fields = list(fields)
    while fields and fields[-1][1].startswith("_padding"):
        fields.pop()
    flat: list[object] = []
    for ftype, fname in fields:
        if fname.startswith("_padding"):
            flat.extend([0] * int(ftype[:-1].split("[")[1]))
        elif "[" in ftype:
            flat.extend(values[fname])
        else:
            flat.append(values[fname])
    return struct.pack(_struct_of(fields), *flat)


def build_ulog(vehicle_status: dict[str, int] | None = None) -> bytes:
    """The bytes of the fixture (deterministic); with ``vehicle_status`` (its fields' values) a
    vehicle_status message at the start as well (the fixture itself has none)."""
    formats = dict(FORMATS)
    if vehicle_status is not None:
        formats["vehicle_status"] = VEHICLE_STATUS
    out = bytearray(b"ULog\x01\x12\x35" + b"\x01" + struct.pack("<Q", 0))
    # Flag bits: no compat or incompat flag, no appended data.
    out += _msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for key, value in (("sys_name", b"PX4"), ("ver_hw", b"SFAP_FIXTURE")):
        key_text = f"char[{len(value)}] {key}".encode()
        out += _msg(b"I", bytes([len(key_text)]) + key_text + value)
    for name, fields in formats.items():
        text = name + ":" + "".join(f"{ft} {fn};" for ft, fn in fields)
        out += _msg(b"F", text.encode())
    msg_ids = {name: i for i, name in enumerate(formats)}
    for name, i in msg_ids.items():
        out += _msg(b"A", struct.pack("<BH", 0, i) + name.encode())

    records: list[tuple[int, int, bytes]] = []  # (timestamp us, order, message)

    def add(t_s: float, name: str, values: dict[str, Any]) -> None:
        ts = round(t_s * 1e6)
        values = {"timestamp": ts, **values}
        payload = struct.pack("<H", msg_ids[name]) + _pack(formats[name], values)
        records.append((ts, len(records), _msg(b"D", payload)))

    if vehicle_status is not None:
        add(1.0, "vehicle_status", vehicle_status)
    for k in range(301):  # GPS, 5 Hz
        t = 5.0 + 0.2 * k
        lat, lon, alt = position(t)
        add(
            t,
            "vehicle_gps_position",
            {
                "time_utc_usec": round(utc_s(t) * 1e6),
                "lat": round(lat * 1e7),
                "lon": round(lon * 1e7),
                "alt": round(alt * 1e3),
                "fix_type": 3,
            },
        )
    for k in range(601):  # global position, 10 Hz
        t = 5.0 + 0.1 * k
        lat, lon, alt = position(t)
        add(t, "vehicle_global_position", {"lat": lat, "lon": lon, "alt": alt})
    for k in range(601):  # attitude, 10 Hz
        t = 5.0 + 0.1 * k
        add(t, "vehicle_attitude", {"q": quaternion(*euler_deg(t))})
    for seq, t in enumerate(TRIGGER_TIMES_S):
        utc_us = round(utc_s(t) * 1e6)
        add(t, "camera_trigger", {"timestamp_utc": utc_us, "seq": seq, "feedback": True})
        lat, lon, alt = position(t)
        add(
            t,
            "camera_capture",
            {
                "timestamp_utc": utc_us,
                "lat": lat,
                "lon": lon,
                "alt": alt,
                "ground_distance": 60.0,
                "q": quaternion(*euler_deg(t)),
                "seq": seq,
                "result": 0 if seq == FAILED_SEQ else 1,
            },
        )
    # A logged string, as PX4 writes them (level '6' = info).
    records.append((5_000_000, -1, _msg(b"L", b"6" + struct.pack("<Q", 5_000_000) + b"sfap fixture")))
    for _, _, m in sorted(records, key=lambda r: (r[0], r[1])):
        out += m
    return bytes(out)


def main(argv: list[str]) -> int:
    target = Path(argv[1]) if len(argv) > 1 else Path(__file__).with_name("px4_survey.ulg")
    target.write_bytes(build_ulog())
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
