"""The ground a check projects frames onto, chosen from what the user gave, never guessed.

Height above ground is the critical unknown of a field check (REFERENCES.md section 5), so
nothing is assumed silently: EXIF altitudes are AMSL and need a ground elevation or a DEM; plan
altitudes are relative to home, over flat ground at home unless a DEM and the take-off elevation
say otherwise. The choice is named in :attr:`GroundChoice.description`. Frames that are not
survey frames over that ground (on the ground, climbing, in transit) are left out and listed.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.camera import Orientation

from .errors import GroundError
from .frames import AltitudeReference, AttitudeSource, Frames, frames_local_frame, local_frame_at
from .plan_frames import PlanInfo
from .survey_frames import ON_GROUND_M, AltitudeTrend

if TYPE_CHECKING:
    from .ground import Ground

log = logging.getLogger(__name__)

#: Lowest camera height above the ground accepted before the ground is called wrong, metres.
MIN_HEIGHT_AGL_M = 1.0


@dataclass(frozen=True, kw_only=True)
class GroundChoice:
    """The ground a check projects onto, the frames in the ground's altitude reference, and
    in words where the ground came from (for the report)."""

    ground: Ground
    frames: Frames
    description: str
    left_out: tuple[tuple[str, str], ...] = ()
    #: What makes the heights unreliable (drifting GPS altitudes and what was done about it).
    warnings: tuple[str, ...] = ()
    #: The trend removed from drifting GPS altitudes (None: not detrended): the check then blames a
    #: measured image scale that disagrees on the heights.
    detrended: AltitudeTrend | None = None


def ground_from_options(
    *,
    frames: Frames,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """Choose the ground from what the user gave; refuse (GroundError) rather than guess.

    - ``dem``: a GeoTIFF of ground elevations above mean sea level (any CRS).
    - ``ground_elevation_m``: flat ground at this elevation above mean sea level.
    - ``takeoff_elevation_m``: elevation above mean sea level of the take-off point.

    Frames with AMSL altitudes need a DEM, a ground elevation or a take-off elevation (flat
    ground at take-off). Frames relative to home lie over flat ground at home unless a DEM or
    a ground elevation is given, which then needs the take-off elevation to put the frames on
    the same reference (their altitudes are rebased to AMSL). AGL frames lie over flat ground at
    0. Frames that are not survey frames over that ground (on the ground, climbing, in transit:
    :mod:`processing.survey_frames`) are left out and listed in ``GroundChoice.left_out``; a
    ground that puts many frames at or under it is refused, unless the GPS altitudes drift (over
    flat ground): then they are detrended about mid-flight (one flying height assumed) and
    ``GroundChoice.warnings`` says so.
    """
    from .ground import DemGround, FlatGround, check_reference

    if dem is not None and ground_elevation_m is not None:
        raise GroundError(
            "both --dem and --ground-elevation-m were given; give one (the DEM for uneven ground, the "
            "elevation for flat ground)"
        )
    for name, value in (
        ("ground_elevation_m", ground_elevation_m),
        ("takeoff_elevation_m", takeoff_elevation_m),
    ):
        if value is not None and not (math.isfinite(value) and -500.0 <= value <= 9000.0):
            raise GroundError(f"{name} = {value} is outside -500..9000 m above mean sea level")
    ref = frames.alt_reference
    ground: Ground
    if ref in (AltitudeReference.AMSL, AltitudeReference.ELLIPSOID):
        what = "above mean sea level" if ref is AltitudeReference.AMSL else "above the WGS84 ellipsoid"
        if dem is not None:
            ground = DemGround.from_geotiff(Path(dem), reference=AltitudeReference.AMSL)
            description = f"DEM {Path(dem).name} (heights AMSL); camera altitudes {what}"
        elif ground_elevation_m is not None or takeoff_elevation_m is not None:
            given = ground_elevation_m if ground_elevation_m is not None else takeoff_elevation_m
            assert given is not None
            where = "the ground" if ground_elevation_m is not None else "the take-off point"
            ground = FlatGround(elevation_m=given, reference=ref, source=f"elevation of {where}, given")
            description = f"flat ground at {given:g} m (elevation of {where}, given); camera altitudes {what}"
        else:
            median = float(np.median(frames.alt_m)) if len(frames) else float("nan")
            raise GroundError(
                f"the camera altitudes are {what} (median {median:.1f} m) and the height above ground is "
                "unknown; give the ground elevation (--ground-elevation-m, metres AMSL) or a DEM (--dem "
                "FILE.tif)"
            )
    elif ref is AltitudeReference.REL_HOME:
        if dem is None and ground_elevation_m is None:
            ground = FlatGround(elevation_m=0.0, reference=ref, source="the take-off point")
            description = (
                "flat ground at the take-off point (altitudes are relative to home; ground that rises or "
                "falls away from home changes the real height: give a DEM to account for it)"
            )
        else:
            if takeoff_elevation_m is None:
                raise GroundError(
                    "the camera altitudes are relative to the take-off point; to use "
                    + ("a DEM" if dem is not None else "a ground elevation")
                    + " give the take-off elevation above mean sea level too "
                    "(--takeoff-elevation-m)"
                )
            frames = replace(
                frames,
                alt_m=frames.alt_m + takeoff_elevation_m,
                alt_reference=AltitudeReference.AMSL,
            )
            if dem is not None:
                ground = DemGround.from_geotiff(Path(dem), reference=AltitudeReference.AMSL)
                description = (
                    f"DEM {Path(dem).name} (heights AMSL); camera altitudes relative to a take-off point at "
                    f"{takeoff_elevation_m:g} m AMSL"
                )
            else:
                assert ground_elevation_m is not None
                ground = FlatGround(
                    elevation_m=ground_elevation_m, reference=AltitudeReference.AMSL, source="given"
                )
                description = (
                    f"flat ground at {ground_elevation_m:g} m AMSL (given); camera altitudes relative to a "
                    f"take-off point at {takeoff_elevation_m:g} m AMSL"
                )
    else:  # AGL
        if dem is not None or ground_elevation_m is not None:
            raise GroundError(
                "the camera altitudes are already above the ground below each frame; drop --dem and "
                "--ground-elevation-m"
            )
        ground = FlatGround(elevation_m=0.0, reference=ref, source="altitudes above ground")
        description = "camera altitudes above the ground below each frame"
    check_reference(ground, frames.alt_reference)
    # GPS altitudes over flat ground only: over a DEM a terrain-following flight's altitudes trend
    # with the ground, and the heights above the DEM are judged as they are.
    gps_over_flat = ref in (AltitudeReference.AMSL, AltitudeReference.ELLIPSOID) and dem is None
    frames, trend, warnings = _undrift(frames) if gps_over_flat else (frames, None, ())
    keep, left_out = _survey_frames(frames, ground, description, drifting=trend is not None)
    return GroundChoice(
        ground=ground,
        frames=frames.select(keep),
        description=description,
        left_out=left_out,
        warnings=warnings,
        detrended=trend,
    )


def _undrift(frames: Frames) -> tuple[Frames, AltitudeTrend | None, tuple[str, ...]]:
    """Frames whose GPS altitudes (AMSL or ellipsoidal, over flat ground) trend by more than
    ALTITUDE_DRIFT_M over the card (:func:`processing.survey_frames.altitude_trend`, and the plain
    least-squares line over all of them agrees), with the trend removed, the trend, and the warning
    that says so; the frames unchanged, None and no warning otherwise (and for a plan's stations)."""
    from .survey_frames import ALTITUDE_DRIFT_M, altitude_trend

    t = frames.time_utc_s
    if (
        t is None
        or frames.attitude_source is AttitudeSource.PLAN
        or frames.alt_reference not in (AltitudeReference.AMSL, AltitudeReference.ELLIPSOID)
    ):
        return frames, None, ()
    trend = altitude_trend(frames.alt_m, t)
    if trend is None or not abs(trend.drift_m) > ALTITUDE_DRIFT_M:
        return frames, None, ()
    # The plain least-squares line over every frame must say so too: a few minutes of frames and one
    # frame long after them (a robust line through them extrapolates a minute's climb) do not drift.
    plain = float(np.polyfit(t - trend.start_s, frames.alt_m, 1)[0]) * trend.span_s
    if not (abs(plain) > ALTITUDE_DRIFT_M and plain * trend.drift_m > 0):
        return frames, None, ()
    warning = (
        "the heights above ground are unreliable: the GPS altitude drifts by "
        f"{trend.drift_m:+.1f} m over the {trend.span_s / 60:.0f} min of the card "
        "(least-squares line of altitude on time); the frames are judged on the detrended altitudes, "
        "assuming the block was flown at one height, the GPS altitude of mid-flight, so heights and GSD "
        "carry that altitude's error (the image scale measured from the pixels, when the frames are "
        "matched, checks it); a relative (barometric) altitude settles it"
    )
    log.warning("%s", warning)
    return replace(frames, alt_m=trend.detrended(frames.alt_m, t)), trend, (warning,)


def plan_dem_path(info: PlanInfo) -> Path | None:
    """The DEM a terrain plan was made on (summary.json ``terrain.dem``), where it can be found:
    in the plan folder, or at the recorded path (absolute, or relative to the working folder)."""
    terrain = info.planned.terrain
    if terrain is None or not terrain.dem:
        return None
    recorded = Path(terrain.dem)
    for candidate in (info.planned.folder / recorded.name, info.planned.folder / recorded, recorded):
        if candidate.is_file():
            return candidate
    return None


def plan_takeoff_elevation_m(info: PlanInfo) -> float | None:
    """The take-off elevation (m AMSL) a terrain plan recorded: its terrain's ground at home."""
    terrain = info.planned.terrain
    return None if terrain is None else terrain.home_ground_amsl_m


def ground_for_plan(
    *,
    frames: Frames,
    info: PlanInfo,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """The ground a plan's own stations are judged on: the plan is the plan.

    A terrain plan (summary.json has ``terrain``) is judged on its own DEM (``dem`` if given,
    else the DEM it recorded, :func:`plan_dem_path`) with its own take-off elevation
    (:func:`plan_takeoff_elevation_m`) unless ``takeoff_elevation_m`` is given. With a DEM and no
    take-off elevation (a flat plan), the take-off elevation is the DEM's at the plan's home. When its DEM
    cannot be found, on the heights above ground the planner computed for each station (over
    flat ground under each frame), and the description says so. A flat plan: as
    :func:`ground_from_options`.
    """
    terrain = info.planned.terrain
    if ground_elevation_m is not None or (terrain is None and dem is None):
        return ground_from_options(
            frames=frames,
            dem=dem,
            ground_elevation_m=ground_elevation_m,
            takeoff_elevation_m=takeoff_elevation_m,
        )
    takeoff = takeoff_elevation_m if takeoff_elevation_m is not None else plan_takeoff_elevation_m(info)
    takeoff_source = "given" if takeoff_elevation_m is not None else "the plan's"
    dem_path = Path(dem) if dem is not None else plan_dem_path(info)
    if dem_path is not None and takeoff is None:
        takeoff = _dem_elevation_at_home(dem_path, info)
        takeoff_source = "the DEM's at the plan's home"
    if dem_path is not None and takeoff is not None:
        choice = ground_from_options(frames=frames, dem=dem_path, takeoff_elevation_m=takeoff)
        source = "given" if dem is not None else "the plan's own"
        return replace(
            choice, description=f"{choice.description} ({source} DEM; take-off elevation {takeoff_source})"
        )
    if terrain is None:
        raise GroundError(
            f"the plan records no home position to read the take-off elevation off {dem}; give it "
            "(--takeoff-elevation-m, metres AMSL)"
        )
    agl = info.planned.stations.alt_agl_m
    if agl is None:
        raise GroundError(
            f"{info.planned.folder} is a terrain plan made on DEM {terrain.dem!r}, which is not in the plan "
            "folder or at that path, and its stations carry no height above ground; give the DEM "
            "(--dem FILE.tif)"
        )
    agl_frames = replace(frames, alt_m=agl, alt_reference=AltitudeReference.AGL)
    choice = ground_from_options(frames=agl_frames)
    return replace(
        choice,
        description=(
            f"the plan's heights above its DEM {terrain.dem!r} at each station (the DEM itself was "
            "not "
            "found: flat ground under each frame; give --dem for footprints over the real relief)"
        ),
    )


def images_ground(
    *,
    frames: Frames,
    plan: PlanInfo | None,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """The ground for images flown from ``plan``: as :func:`ground_from_options`, except that
    with neither a DEM nor a ground elevation given, a terrain plan's own DEM (found by
    :func:`plan_dem_path`) is the ground, with the plan's take-off elevation for altitudes
    relative to home (unless ``takeoff_elevation_m`` is given)."""
    plan_dem = plan_dem_path(plan) if plan is not None else None
    if dem is None and ground_elevation_m is None and plan is not None and plan_dem is not None:
        takeoff = takeoff_elevation_m
        if takeoff is None and frames.alt_reference is AltitudeReference.REL_HOME:
            takeoff = plan_takeoff_elevation_m(plan)
        choice = ground_from_options(frames=frames, dem=plan_dem, takeoff_elevation_m=takeoff)
        return replace(choice, description=f"{choice.description} (the plan's own DEM)")
    return ground_from_options(
        frames=frames, dem=dem, ground_elevation_m=ground_elevation_m, takeoff_elevation_m=takeoff_elevation_m
    )


def _dem_elevation_at_home(dem: Path, info: PlanInfo) -> float | None:
    """The ground elevation (m AMSL) at the plan's home on ``dem``: the take-off point is on the
    ground. None when the plan records no home or the DEM does not cover it."""
    from .ground import DemGround

    home = info.planned.home
    if home is None:
        return None
    frame = local_frame_at(home.lon_deg, home.lat_deg)
    ground = DemGround.from_geotiff(dem, reference=AltitudeReference.AMSL)
    try:
        return float(np.asarray(ground.elevation_at(np.array([0.0]), np.array([0.0]), frame))[0])
    except GroundError:
        return None


def _survey_frames(
    frames: Frames, ground: Ground, description: str, *, drifting: bool = False
) -> tuple[np.ndarray, tuple[tuple[str, str], ...]]:
    """The survey frames over ``ground`` (:mod:`processing.survey_frames`) and the others with
    their reasons; GroundError when the ground itself must be wrong (most frames at or under it),
    unless the altitudes were detrended (``drifting``: the drift, not the ground, is then what is
    wrong, and the warning says so)."""
    from .survey_frames import select_survey_frames

    if len(frames) == 0:
        return np.zeros(0, dtype=bool), ()
    frame = frames_local_frame(frames)
    x, y = frame.to_xy(frames.lon_deg, frames.lat_deg)
    elevation = np.asarray(ground.elevation_at(x, y, frame), dtype=np.float64)
    height = frames.alt_m - elevation
    airborne = height > MIN_HEIGHT_AGL_M
    median = float(np.median(height[airborne])) if airborne.any() else 0.0
    frame_length_m = (
        max(frames.camera.footprint(median, Orientation.LANDSCAPE).along_m, 1.0) if median > 0 else None
    )
    plan = frames.attitude_source is AttitudeSource.PLAN
    xy = None if plan else np.column_stack([x, y])
    selection = select_survey_frames(height, xy, frame_length_m, alt_m=frames.alt_m, time_s=frames.time_utc_s)
    if plan:  # every station of a plan is a survey frame; only the ground is judged
        selection = replace(selection, keep=np.ones(len(frames), dtype=bool), left_out=())
    if (selection.ground_suspect and not drifting) or not selection.keep.any():
        low = ~(height >= MIN_HEIGHT_AGL_M)
        k = int(np.argmin(height))
        raise GroundError(
            f"{int((height <= ON_GROUND_M).sum())} of {len(frames)} frame(s) are within a few metres of "
            f"the ground or under it, {int(low.sum())} less than {MIN_HEIGHT_AGL_M:g} m above it "
            f"({description}); e.g. {frames.name[k]} at {frames.alt_m[k]:.1f} m over ground at "
            f"{elevation[k]:.1f} m: check the ground elevation (metres AMSL) or the DEM; camera altitudes "
            "above the WGS84 ellipsoid where mean sea level is expected are tens of metres off"
        )
    left = tuple((frames.name[k], why) for k, why in selection.left_out)
    if left:
        from .survey_frames import left_out_summary

        log.warning(
            "%d frame(s) are not survey frames and are left out (all in the report): %s",
            len(left),
            left_out_summary(left),
        )
    return selection.keep, left
