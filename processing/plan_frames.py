"""A plan folder as frames: what a check of a plan (before the flight) starts from.

- :func:`read_plan_info`: the plan folder as :func:`planner.plan_folder.read_plan_folder`
  reads it, and the camera it was planned for.
- :func:`frames_from_plan`: every planned station as a frame, altitudes relative to home.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from planner.camera import Camera, Orientation
from planner.camera_db import get_camera
from planner.errors import CameraError
from planner.plan_folder import STATIONS_FILE, SUMMARY_FILE, PlanFolder, read_plan_folder

from .errors import FramesError
from .frames import AltitudeReference, AttitudeSource, Frames


@dataclass(frozen=True, kw_only=True)
class PlanInfo:
    """What a check needs from a plan folder: the folder as read (``planned``: its summary,
    home, stations, area and terrain) and the camera it was planned for."""

    planned: PlanFolder
    camera: Camera


def read_plan_info(plan_dir: str | os.PathLike[str], *, camera: Camera | None = None) -> PlanInfo:
    """The plan's numbers and area from a folder written by ``sfap plan``.

    ``camera``: needed only when the plan used a custom camera (summary.json names the
    camera by id, and a custom camera is not in the database). Raises
    :class:`~planner.errors.PlanFolderError` for a folder that is not a plan folder or a file
    that cannot be read, FramesError for a camera that is not in the database.
    """
    planned = read_plan_folder(plan_dir)
    try:
        used = camera if camera is not None else get_camera(planned.summary.camera_id)
    except CameraError as error:
        raise FramesError(
            f"{planned.folder / SUMMARY_FILE}: {error}; a plan made with a custom camera needs that camera "
            "given to the check"
        ) from None
    return PlanInfo(planned=planned, camera=used)


def frames_from_plan(
    plan_dir: str | os.PathLike[str], *, camera: Camera | None = None
) -> tuple[Frames, PlanInfo]:
    """Every planned station of a plan folder as a frame, and the plan's numbers.

    Altitudes are relative to home (:attr:`AltitudeReference.REL_HOME`). Attitude (the module
    docstring of :mod:`processing.frames`): yaw is the bearing of the image top: the look
    heading for tilted (oblique) stations, for nadir stations the flight heading in landscape
    and heading - 90 in portrait; pitch is the tilt off nadir; roll 0. ``line_index`` numbers
    the (pass, line) pairs in flight order, so lines of different passes stay apart.
    """
    info = read_plan_info(plan_dir, camera=camera)
    st = info.planned.stations
    if len(st) == 0:
        raise FramesError(
            f"{info.planned.folder / STATIONS_FILE} holds no station; the plan has no photo to check"
        )
    landscape = info.planned.orientation is Orientation.LANDSCAPE
    nadir_up = st.heading_deg % 360.0 if landscape else (st.heading_deg - 90.0) % 360.0
    yaw = np.where(st.tilt_deg > 0.0, st.look_heading_deg % 360.0, nadir_up)
    line_ids: dict[tuple[int, int], int] = {}
    line_index = np.array(
        [
            line_ids.setdefault((int(a), int(b)), len(line_ids))
            for a, b in zip(st.pass_index, st.line_index, strict=True)
        ],
        dtype=np.int32,
    )
    frames = Frames(
        name=tuple(f"{a}-{b}-{s}" for a, b, s in zip(st.pass_index, st.line_index, st.station, strict=True)),
        lon_deg=st.lon_deg,
        lat_deg=st.lat_deg,
        alt_m=st.alt_rel_home_m,
        alt_reference=AltitudeReference.REL_HOME,
        yaw_deg=yaw,
        pitch_deg=st.tilt_deg,
        roll_deg=np.zeros_like(yaw),
        attitude_source=AttitudeSource.PLAN,
        camera=info.camera,
        time_utc_s=None,
        exposure_s=None,
        line_index=line_index,
    )
    return frames, info
