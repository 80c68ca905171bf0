"""Ground control against the block and against a model.

:func:`validate_control` runs before anything is written: every observation must name an image
of the block and lie inside it, and at least three control points must be seen in two frames
or more. :func:`control_accuracy` places a model by the control points and measures control and
check residuals (:func:`processing.accuracy.assess_accuracy`) in a local metric frame around the
points (:func:`processing.frames.local_frame_at`: metres east and north, z the surveyed elevation).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.geo import LocalFrame

from ..accuracy import MIN_CONTROL_POINTS, AccuracyResult, View, assess_accuracy, heights_unknown
from ..frames import local_frame_at
from ..gcp import GcpSet, choose_check_points
from .block import Block
from .errors import HandoffInputError

F64 = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class ControlPlan:
    gcps: GcpSet
    frame: LocalFrame
    ground_xyz_m: dict[str, F64]
    control: tuple[str, ...]
    check: tuple[str, ...]
    notes: tuple[str, ...]

    def surveyed_distance_m(self, a: str, b: str) -> float:
        return float(np.linalg.norm(self.ground_xyz_m[a] - self.ground_xyz_m[b]))


def validate_control(gcps: GcpSet, block: Block, check_points: str | None) -> ControlPlan:
    """Check the GCP file against the block and split control from check points."""
    row = {n: k for k, n in enumerate(block.names)}
    unknown = sorted({o.image for o in gcps.observations if o.image not in row})
    if unknown:
        raise HandoffInputError(
            f"{gcps.source}: {len(unknown)} image name(s) match no frame in {block.image_dir}: "
            + ", ".join(unknown[:8])
            + ("..." if len(unknown) > 8 else "")
            + "; fix the names in the GCP file (they are case-sensitive) or add the images"
        )
    for o in gcps.observations:
        intr = block.intrinsics[block.camera_index[row[o.image]]]
        if not (0.0 <= o.x_px < intr.width_px and 0.0 <= o.y_px < intr.height_px):
            raise HandoffInputError(
                f"{gcps.source}: point {o.point} in {o.image} at pixel ({o.x_px:g}, {o.y_px:g}) is "
                "outside the "
                f"image ({intr.width_px} x {intr.height_px} px); pixel coordinates are from the top-left "
                "corner of the full-size image (were they measured on a resized copy?)"
            )
    seen = {p.name: len({o.image for o in gcps.observations_of(p.name)}) for p in gcps.points}
    usable = [p.name for p in gcps.points if seen[p.name] >= 2]
    notes = [
        f"{name}: seen in {count} image(s), needs two: listed, not used"
        for name, count in seen.items()
        if count < 2
    ]
    lon = np.array([gcps.point(n).lon_deg for n in gcps.names])
    lat = np.array([gcps.point(n).lat_deg for n in gcps.names])
    frame = local_frame_at(float(np.median(lon)), float(np.median(lat)))
    x, y = frame.to_xy(lon, lat)
    ground = {n: np.array([x[k], y[k], gcps.point(n).elevation_m]) for k, n in enumerate(gcps.names)}
    xy = np.array([ground[n][:2] for n in usable]).reshape(-1, 2)
    control, check = choose_check_points(usable, xy, check_points)
    if len(control) < MIN_CONTROL_POINTS:
        raise HandoffInputError(
            f"{gcps.source}: {len(control)} usable control point(s) ({', '.join(control) or 'none'}) after "
            f"{len(check)} check point(s); {MIN_CONTROL_POINTS} are needed, each marked in two images or "
            "more: mark more points or choose fewer check points"
        )
    if heights_unknown(ground):
        notes.append(
            "every elevation in the GCP file is 0.0: the surveyed heights are unknown, so the model is "
            "placed by the horizontal positions alone (scale, rotation, east, north) and Z is not measured "
            "(a fit to the 0.0 heights would flatten the real relief: wrong scale and tilt)"
        )
    return ControlPlan(
        gcps=gcps,
        frame=frame,
        ground_xyz_m=ground,
        control=control,
        check=check,
        notes=tuple(notes),
    )


def control_accuracy(plan: ControlPlan, views: Mapping[str, View]) -> AccuracyResult:
    """Place the model (its registered ``views``) by the control points; residuals at both sets."""
    return assess_accuracy(
        ground_xyz_m=plan.ground_xyz_m,
        observations=plan.gcps.observations,
        views=views,
        control=plan.control,
        check=plan.check,
        heights_known=not heights_unknown(plan.ground_xyz_m),
    )


def check_distances(plan: ControlPlan, result: AccuracyResult) -> list[dict[str, float | str]]:
    """Every distance between two placed check points against the surveyed one (horizontal,
    since surveyed elevations may be unknown), metres."""
    names = [n for n in plan.check if n in result.placed_xyz_m]
    rows: list[dict[str, float | str]] = []
    for k, a in enumerate(names):
        for b in names[k + 1 :]:
            surveyed = float(np.linalg.norm(plan.ground_xyz_m[a][:2] - plan.ground_xyz_m[b][:2]))
            model = float(np.linalg.norm(result.placed_xyz_m[a][:2] - result.placed_xyz_m[b][:2]))
            rows.append(
                {"a": a, "b": b, "surveyed_m": surveyed, "model_m": model, "difference_m": model - surveyed}
            )
    return rows
