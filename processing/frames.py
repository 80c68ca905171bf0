"""The frames a coverage check works on: geotagged images, or a plan's stations.

Camera attitude follows the Pix4D / OpenDroneMap camera convention, which the XMP tags
``Camera:Yaw/Pitch/Roll`` carry: (0, 0, 0) is a camera looking straight down with the top of
the image toward north; ``yaw_deg`` turns it clockwise seen from above (the bearing of the image
top), ``pitch_deg`` tilts the optical axis off nadir toward the image top, ``roll_deg`` turns it
about the image's vertical axis, positive right wing down (the aircraft convention: a belly
camera then looks to the image's left). With roll 0, (yaw, pitch) are exactly the
(``up_bearing_deg``, ``tilt_deg``) of :mod:`planner.footprint`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray
from pyproj import CRS

from planner.camera import Camera
from planner.geo import LocalFrame

F64 = NDArray[np.float64]


class AltitudeReference(StrEnum):
    AMSL = "amsl"  # above mean sea level (EXIF GPSAltitude, usually)
    ELLIPSOID = "ellipsoid"  # above the WGS84 ellipsoid
    REL_HOME = "rel_home"  # above the take-off point
    AGL = "agl"  # above the ground below the camera


class AttitudeSource(StrEnum):
    XMP = "xmp"  # the image's own XMP camera tags
    PLAN = "plan"  # a planned station
    ASSUMED_NADIR = "assumed_nadir"  # none recorded: nadir, image top along the track


@dataclass(frozen=True, kw_only=True)
class Frames:
    """One row per frame; columns are numpy arrays of equal length (tuple for names).

    - ``name``: image file name (or ``"pass-line-station"`` for planned stations).
    - ``lon_deg``, ``lat_deg``: WGS84 camera position.
    - ``alt_m``: camera altitude, referenced as ``alt_reference`` says.
    - ``yaw_deg``, ``pitch_deg``, ``roll_deg``: camera attitude (module docstring).
    - ``time_utc_s``: capture time, POSIX seconds UTC, or None when not known (plan).
    - ``exposure_s``: exposure time from EXIF, or None.
    - ``line_index``: the flight line of each frame when known (plan), else None.
    """

    name: tuple[str, ...]
    lon_deg: F64
    lat_deg: F64
    alt_m: F64
    alt_reference: AltitudeReference
    yaw_deg: F64
    pitch_deg: F64
    roll_deg: F64
    attitude_source: AttitudeSource
    camera: Camera
    time_utc_s: F64 | None = None
    exposure_s: F64 | None = None
    line_index: NDArray[np.int32] | None = None

    def __post_init__(self) -> None:
        n = len(self.name)
        for key in ("lon_deg", "lat_deg", "alt_m", "yaw_deg", "pitch_deg", "roll_deg"):
            value = getattr(self, key)
            if value.shape != (n,):
                raise ValueError(f"Frames.{key} has shape {value.shape}, expected ({n},)")

    def __len__(self) -> int:
        return len(self.name)

    def select(self, keep: NDArray[np.bool_] | NDArray[np.intp]) -> Frames:
        """The frames at ``keep`` (a boolean mask or row indices), every column alike."""
        index = np.flatnonzero(keep) if np.asarray(keep).dtype == np.bool_ else np.asarray(keep, np.intp)

        def take(value: F64 | None) -> F64 | None:
            return None if value is None else np.asarray(value)[index]

        line = None if self.line_index is None else self.line_index[index]
        return Frames(
            name=tuple(self.name[int(k)] for k in index),
            lon_deg=self.lon_deg[index],
            lat_deg=self.lat_deg[index],
            alt_m=self.alt_m[index],
            alt_reference=self.alt_reference,
            yaw_deg=self.yaw_deg[index],
            pitch_deg=self.pitch_deg[index],
            roll_deg=self.roll_deg[index],
            attitude_source=self.attitude_source,
            camera=self.camera,
            time_utc_s=take(self.time_utc_s),
            exposure_s=take(self.exposure_s),
            line_index=line,
        )


def local_frame_at(lon_deg: float, lat_deg: float) -> LocalFrame:
    """A transverse Mercator frame (WGS84, scale 1) centred on a point, metres east and north.

    Grid north is true north along its central meridian, so a bearing (a camera's yaw, a
    flight heading) is a grid bearing to within the meridian convergence a few kilometres
    away (0.01 deg at 1 km): unlike a UTM zone, whose grid north is off true north by up to
    3 deg at the zone's edges, which would turn every footprint about its camera. Distances
    are true to 1e-8 within a few kilometres.
    """
    crs = CRS.from_proj4(
        f"+proj=tmerc +lat_0={lat_deg!r} +lon_0={lon_deg!r} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
    )
    return LocalFrame.from_crs(crs)


def frames_local_frame(frames: Frames) -> LocalFrame:
    """The frame a check of ``frames`` works in: :func:`local_frame_at` their median position."""
    return local_frame_at(float(np.median(frames.lon_deg)), float(np.median(frames.lat_deg)))
