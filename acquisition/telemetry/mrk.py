"""DJI RTK photo event files (``*_Timestamp.MRK``: Phantom 4 RTK, Matrice 3E/300/350, Mavic 3
Enterprise RTK...) -> :class:`~acquisition.telemetry.model.FlightLog` (camera events).

One text line per photo, tab-separated, 13 columns (DJI user manuals, "Image Log File").
An example line from a real file, its tabs shown as `` | `` and wrapped here::

    1 | 282401.669089 | [2404] |    101,N |    107,E |    129,V | 22.77995359,Lat |
    114.10089118,Lon | 139.231,Ellh | 0.002967, 0.003104, 0.007622 | 50,Q

1. photo number (the N in ``..._000N.JPG``);
2. exposure time, GPS seconds of week; 3. GPS week, in brackets;
4-6. offsets from the GNSS antenna phase centre to the centre of the camera's CMOS, in
   millimetres: north (positive north), east (positive east), vertical (positive
   **downward**), each followed by ``,N`` ``,E`` ``,V``;
7-8. latitude and longitude after that compensation (the camera's position), degrees, with
   ``,Lat`` ``,Lon``;
9. ellipsoidal height (WGS84), metres, ``,Ellh``;
10-12. standard deviations north, east, vertical, metres (comma-separated);
13. positioning status ``,Q``: 0 no fix, 16 single point, 34 RTK float, 50 RTK fixed.

:func:`read_mrk_table` returns every column (:class:`MrkEvents`); :func:`read_mrk` the shared
tables. The ellipsoidal height has no column in :class:`CameraEvents` (it is not AMSL): the
event altitudes stay None there and a warning says so.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import TelemetryError
from .gpstime import gps_week_tow_to_utc_s, time_order
from .model import CameraEvents, FlightLog, flight_log

F64 = NDArray[np.float64]

_NUM = r"[-+]?\d+(?:\.\d+)?"
MRK_LINE = re.compile(
    rf"^\s*(\d+)\s+({_NUM})\s+\[(\d+)\]\s+({_NUM}),N\s+({_NUM}),E\s+({_NUM}),V\s+"
    rf"({_NUM}),Lat\s+({_NUM}),Lon\s+({_NUM}),Ellh\s+({_NUM}),\s*({_NUM}),\s*({_NUM})"
    rf"\s+(\d+),Q\s*$"
)
#: The start of an MRK line, enough to recognise the format.
MRK_SIGNATURE = re.compile(rf"^\s*\d+\s+{_NUM}\s+\[\d+\]\s+{_NUM},N\s")

RTK_FIXED = 50
RTK_STATUS_NAMES = {0: "no fix", 16: "single point", 34: "RTK float", 50: "RTK fixed"}


@dataclass(frozen=True, kw_only=True)
class MrkEvents:
    """Every column of an MRK file, one row per photo, in time order.

    ``time_utc_s`` UTC POSIX seconds; ``seq`` photo number; ``gps_week``, ``gps_tow_s`` as
    logged; ``offset_north_mm``, ``offset_east_mm``, ``offset_down_mm`` antenna-to-CMOS
    compensation; ``lat_deg``, ``lon_deg`` camera position; ``alt_ellipsoid_m`` WGS84
    ellipsoidal height; ``std_north_m``, ``std_east_m``, ``std_vert_m`` one-sigma accuracies;
    ``rtk_status`` 0/16/34/50; ``line`` the line each row came from.
    """

    time_utc_s: F64
    seq: NDArray[np.int64]
    gps_week: NDArray[np.int64]
    gps_tow_s: F64
    offset_north_mm: F64
    offset_east_mm: F64
    offset_down_mm: F64
    lat_deg: F64
    lon_deg: F64
    alt_ellipsoid_m: F64
    std_north_m: F64
    std_east_m: F64
    std_vert_m: F64
    rtk_status: NDArray[np.int64]
    line: NDArray[np.int64]

    def __post_init__(self) -> None:
        n = self.time_utc_s.shape[0]
        for name, value in vars(self).items():
            if value.shape != (n,):
                raise TelemetryError(f"MrkEvents.{name} has shape {value.shape}, expected ({n},)")

    def __len__(self) -> int:
        return int(self.time_utc_s.shape[0])


def read_mrk_table(path: str | os.PathLike[str]) -> MrkEvents:
    """Parse an MRK file; a line that does not fit the layout raises :class:`TelemetryError`
    naming it (blank lines are skipped)."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8-sig", errors="strict") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise TelemetryError(f"cannot read {p}: {exc}") from exc
    rows: list[tuple[float, ...]] = []
    for number, text in enumerate(lines, start=1):
        if not text.strip():
            continue
        m = MRK_LINE.match(text)
        if not m:
            raise TelemetryError(
                f"{p}, line {number}: {text.strip()[:120]!r} is not an MRK photo line (expected "
                f"'photo tow [week] n,N e,E v,V lat,Lat lon,Lon h,Ellh sn, se, sv status,Q')"
            )
        values = tuple(float(g) for g in m.groups())
        lat, lon = values[6], values[7]
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise TelemetryError(f"{p}, line {number}: latitude {lat}, longitude {lon} out of range")
        if not 0 <= values[1] < 604_800:
            raise TelemetryError(f"{p}, line {number}: GPS time of week {values[1]} s is outside 0..604800")
        rows.append((*values, float(number)))
    if not rows:
        raise TelemetryError(f"{p}: no photo line in the MRK file")
    a = np.array(rows, dtype=np.float64)
    t = gps_week_tow_to_utc_s(a[:, 2], a[:, 1])
    o = time_order(t, a[:, 0])
    return MrkEvents(
        time_utc_s=t[o],
        seq=a[o, 0].astype(np.int64),
        gps_week=a[o, 2].astype(np.int64),
        gps_tow_s=a[o, 1],
        offset_north_mm=a[o, 3],
        offset_east_mm=a[o, 4],
        offset_down_mm=a[o, 5],
        lat_deg=a[o, 6],
        lon_deg=a[o, 7],
        alt_ellipsoid_m=a[o, 8],
        std_north_m=a[o, 9],
        std_east_m=a[o, 10],
        std_vert_m=a[o, 11],
        rtk_status=a[o, 12].astype(np.int64),
        line=a[o, 13].astype(np.int64),
    )


def read_mrk(path: str | os.PathLike[str]) -> FlightLog:
    """Read an MRK file as camera events (see the module docstring)."""
    p = os.fspath(path)
    table = read_mrk_table(p)
    warnings = [
        f"{p}: MRK heights are WGS84 ellipsoidal (Ellh), not AMSL; CameraEvents has no "
        f"ellipsoidal column, so event altitudes are left empty (read_mrk_table has them)"
    ]
    not_fixed = table.rtk_status != RTK_FIXED
    if not_fixed.any():
        kinds = ", ".join(
            f"{int((table.rtk_status == s).sum())} {RTK_STATUS_NAMES.get(int(s), f'status {s}')}"
            for s in np.unique(table.rtk_status[not_fixed])
        )
        warnings.append(f"{p}: {int(not_fixed.sum())} of {len(table)} photos not RTK fixed ({kinds})")
    events = CameraEvents(
        time_utc_s=table.time_utc_s, seq=table.seq, lat_deg=table.lat_deg, lon_deg=table.lon_deg, source="mrk"
    )
    return flight_log(p, "mrk", warnings, events=events)
