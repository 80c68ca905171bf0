"""What a check starts from, gathered from a folder: a plan folder's stations, or the images of a
flown folder (with the plan they followed, if given), and the ground they are judged on.

:func:`gather_inputs` is the first step of ``sfap check``; :func:`processing.check.run_check`
takes its :class:`CheckInputs` on.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.camera import Camera
from planner.plan_folder import is_plan_folder

from .errors import FramesError
from .frames import Frames
from .ground import Ground
from .ground_choice import GroundChoice, ground_for_plan, images_ground
from .image_frames import image_paths, read_image_frames
from .plan_frames import PlanInfo, frames_from_plan, read_plan_info
from .survey_frames import AltitudeTrend


@dataclass(frozen=True, kw_only=True)
class CheckInputs:
    """The frames to check (survey frames only, in ``ground``'s altitude reference), the ground
    and in words where it came from, the plan they follow (None: no plan), and what the report
    says of the inputs: notes, warnings, images without a position, frames left out with why,
    how the camera was found."""

    frames: Frames
    ground: Ground
    ground_description: str
    plan: PlanInfo | None
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    unpositioned: tuple[str, ...] = ()
    left_out: tuple[tuple[str, str], ...] = ()
    camera_source: str = ""
    camera_confidence: str = ""
    image_dir: Path | None = None
    #: The trend removed from drifting GPS altitudes (None: not detrended).
    detrended: AltitudeTrend | None = None


def gather_inputs(
    source: str | os.PathLike[str],
    *,
    plan_dir: str | os.PathLike[str] | None = None,
    camera: Camera | None = None,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CheckInputs:
    """The inputs of a check of ``source``: a plan folder (its stations, judged on the plan's own
    ground: :func:`processing.ground_choice.ground_for_plan`) or a folder of geotagged images
    (flown from ``plan_dir`` if given: :func:`processing.ground_choice.images_ground`).

    ``camera``: the camera, None to find it (images: their EXIF, else the plan's camera);
    ``dem``, ``ground_elevation_m`` (m AMSL), ``takeoff_elevation_m`` (m AMSL): the ground, as
    :func:`processing.ground_choice.ground_from_options`; ``progress(done, total)`` after each
    image read.
    """
    ground: dict[str, Any] = {
        "dem": dem,
        "ground_elevation_m": ground_elevation_m,
        "takeoff_elevation_m": takeoff_elevation_m,
    }
    if is_plan_folder(source):
        if plan_dir is not None:
            raise FramesError(f"{source} is a plan folder already; give no other plan folder")
        frames, plan = frames_from_plan(source, camera=camera)
        choice = ground_for_plan(frames=frames, info=plan, **ground)
        return _inputs(
            choice,
            plan,
            notes=("frames are the plan's stations (attitude as planned)",),
            left_out=choice.left_out,
        )
    flown_plan = read_plan_info(Path(plan_dir)) if plan_dir is not None else None
    total = len(image_paths(source))
    done = [0]

    def advance(n: int) -> None:
        done[0] += n
        if progress is not None:
            progress(done[0], total)

    images = read_image_frames(
        source, camera=camera, fallback_camera=flown_plan.camera if flown_plan else None, progress=advance
    )
    choice = images_ground(frames=images.frames, plan=flown_plan, **ground)
    return _inputs(
        choice,
        flown_plan,
        notes=(f"camera: {images.camera_source}", *images.notes),
        warnings=(*images.warnings, *choice.warnings),
        unpositioned=images.unpositioned,
        left_out=(*images.left_out, *choice.left_out),
        camera_source=images.camera_source,
        camera_confidence=images.camera_confidence,
        image_dir=Path(source),
    )


def _inputs(choice: GroundChoice, plan: PlanInfo | None, **said: Any) -> CheckInputs:
    """The frames and ground chosen, the plan, and what the report says of the inputs."""
    return CheckInputs(
        frames=choice.frames,
        ground=choice.ground,
        ground_description=choice.description,
        plan=plan,
        detrended=choice.detrended,
        **said,
    )
