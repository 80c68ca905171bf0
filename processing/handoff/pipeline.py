"""``handoff``: one function from an image folder to a finished project folder.

The project is built in a staging folder beside WORK and moved into place only when complete
(:func:`planner.outputs.staged_output_dir`): on any error, or Ctrl-C, nothing is left.
A block that was run but did not reconstruct is a complete result (its report says why) with
exit code 1.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from planner.camera import Camera
from planner.outputs import check_output_dir, staged_output_dir

from ..accuracy import table_3_2
from ..gcp import GcpSet, read_gcp
from .control import ControlPlan, check_distances, control_accuracy, validate_control
from .errors import HandoffInputError
from .prepare import GroundOptions, Prepared, prepare
from .quicklook import (
    DEFAULT_MAPPER,
    DEFAULT_MAX_FEATURES,
    DEFAULT_MAX_IMAGE_SIZE_PX,
    DEFAULT_SIFT_FIRST_OCTAVE,
    MAPPERS,
    SIFT_FIRST_OCTAVES,
    QuickLook,
)

log = logging.getLogger(__name__)

#: Where the largest model goes when the ground control (not GPS) places it.
PLACED_BY_CONTROL = "sparse/placed_by_control"


class Engine(StrEnum):
    COLMAP = "colmap"
    ODM = "odm"
    METASHAPE = "metashape"
    PIX4D = "pix4d"
    NODEODM = "nodeodm"


@dataclass(frozen=True, kw_only=True)
class HandoffOptions:
    engine: Engine
    run: bool = False
    gcp: Path | None = None
    gcp_crs: str | None = None
    check_points: str | None = None
    ground: GroundOptions = field(default_factory=GroundOptions)
    min_overlap_pct: float = 5.0
    line_neighbours: int = 2
    max_image_size_px: int = DEFAULT_MAX_IMAGE_SIZE_PX
    max_features: int = DEFAULT_MAX_FEATURES
    mapper: str = DEFAULT_MAPPER
    sift_first_octave: int = DEFAULT_SIFT_FIRST_OCTAVE
    overwrite: bool = False
    node_url: str | None = None
    token: str = ""
    camera: Camera | None = None


@dataclass(frozen=True, kw_only=True)
class HandoffResult:
    work: Path
    report: dict[str, Any]
    quicklook: QuickLook | None = None
    passed: bool = True  # False: --run found a block that does not reconstruct (sfap exits 1)
    messages: tuple[str, ...] = field(default_factory=tuple)


def _load_control(options: HandoffOptions, prepared: Prepared) -> tuple[GcpSet | None, ControlPlan | None]:
    if options.gcp is None:
        if options.check_points:
            raise HandoffInputError("--check-points needs ground control: give --gcp FILE")
        return None, None
    gcps = read_gcp(options.gcp, crs=options.gcp_crs)
    return gcps, validate_control(gcps, prepared.block, options.check_points)


def handoff(
    images: str | os.PathLike[str],
    work: str | os.PathLike[str],
    options: HandoffOptions,
    *,
    progress: Callable[[str], None] | None = None,
) -> HandoffResult:
    """Write the ``options.engine`` project for ``images`` into ``work`` (and run it for COLMAP
    with ``options.run``)."""
    from .report import accuracy_dict, distances_text, quicklook_dict, report_html, write_json

    if options.run and options.engine is not Engine.COLMAP:
        raise HandoffInputError(f"--run runs COLMAP only; drop --run for --to {options.engine.value}")
    if options.mapper not in MAPPERS:
        raise HandoffInputError(f"--mapper {options.mapper!r}: choose {' or '.join(MAPPERS)}")
    if not (100 <= options.max_features <= 100000):
        raise HandoffInputError(f"--max-features {options.max_features} is outside 100..100000")
    if options.sift_first_octave not in SIFT_FIRST_OCTAVES:
        raise HandoffInputError(
            f"--sift-first-octave {options.sift_first_octave}: choose "
            + " or ".join(map(str, SIFT_FIRST_OCTAVES))
        )
    if not (200 <= options.max_image_size_px <= 20000):
        raise HandoffInputError(f"--max-image-size-px {options.max_image_size_px} is outside 200..20000")
    address = None
    if options.engine is Engine.NODEODM:
        from .nodeodm import parse_node_url

        if options.node_url is None:
            raise HandoffInputError("--to nodeodm needs the node's address: nodeodm://HOST:PORT")
        address = parse_node_url(options.node_url)  # a bad address is refused before any work
    check_output_dir(work, overwrite=options.overwrite)
    say = progress or (lambda text: None)
    say("reading the frames")
    prepared = prepare(
        images,
        ground=options.ground,
        min_overlap_pct=options.min_overlap_pct,
        line_neighbours=options.line_neighbours,
        camera=options.camera,
    )
    gcps, plan = _load_control(options, prepared)
    from .colmap_project import project_info

    report: dict[str, Any] = {"engine": options.engine.value, "project": project_info(prepared)}
    if plan is not None:
        report["control"] = {
            "control": list(plan.control),
            "check": list(plan.check),
            "notes": list(plan.notes),
        }
    quick: QuickLook | None = None
    passed = True
    with staged_output_dir(work, overwrite=options.overwrite) as stage:
        if options.engine is Engine.COLMAP:
            from .colmap_project import write_colmap_project

            say("writing the COLMAP database and pairs")
            write_colmap_project(prepared, stage)
            if options.run:
                from .quicklook import run_quicklook

                quick = run_quicklook(
                    prepared,
                    stage,
                    max_image_size_px=options.max_image_size_px,
                    max_features=options.max_features,
                    mapper=options.mapper,
                    sift_first_octave=options.sift_first_octave,
                    progress=say,
                )
                report["quicklook"] = quicklook_dict(quick)
                passed = quick.reconstructs
                if plan is not None and quick.largest is not None:
                    say("accuracy: control and check points")
                    acc = control_accuracy(plan, quick.largest.views)
                    distances = check_distances(plan, acc)
                    report["accuracy"] = accuracy_dict(acc, distances, plan.notes)
                    if quick.georegistration is None:
                        # No GPS placed the model: the control does, in the frame of the points.
                        from . import colmap_adapter as colmap
                        from .block import proj_string

                        s = acc.similarity
                        placed = colmap.transform_model(quick.largest, s.scale, s.rotation, s.translation_m)
                        colmap.write_model(placed, stage / PLACED_BY_CONTROL)
                        report["accuracy"]["model"] = {
                            "folder": PLACED_BY_CONTROL,
                            "frame_proj": proj_string(plan.frame),
                            "z": "surveyed elevation"
                            if acc.heights_known
                            else "height above the control points' mean (their elevations are unknown)",
                        }
                        report["quicklook"]["messages"] = [
                            m for m in report["quicklook"]["messages"] if "not georegistered" not in m
                        ] + [f"the model is placed by the ground control: {PLACED_BY_CONTROL}"]
                    report["accuracy"]["table_3_2"] = "\n".join(
                        t for t in (table_3_2(acc), distances_text(distances)) if t
                    )
        elif options.engine is Engine.NODEODM:
            from .nodeodm import run_on_node
            from .odm import GCP_TXT, GEO_TXT, write_odm_project

            assert address is not None
            say("writing the ODM project")
            report["odm"] = write_odm_project(prepared.block, prepared.pairs, gcps, stage)
            files = [stage / "images" / n for n in prepared.block.names]
            files += [stage / f for f in (GEO_TXT, GCP_TXT) if (stage / f).exists()]
            run = run_on_node(
                address,
                token=options.token,
                files=files,
                options=report["odm"]["options"],
                name=Path(work).name,
                results_dir=stage / "results",
                progress=say,
            )
            report["nodeodm"] = run.as_dict()
        elif options.engine is Engine.ODM:
            from .odm import write_odm_project

            say("writing the ODM project")
            report["odm"] = write_odm_project(prepared.block, prepared.pairs, gcps, stage)
        else:
            from .odm import write_reference

            say(f"writing the {options.engine.value} reference files")
            report[options.engine.value] = write_reference(prepared.block, gcps, stage, options.engine.value)
            passed = bool(report[options.engine.value]["complete"])  # no camera positions: exit 1
        (stage / "report.json").write_text(write_json(report), encoding="utf-8")
        if options.engine is Engine.COLMAP:
            (stage / "report.html").write_text(report_html(report, quick), encoding="utf-8")
    return HandoffResult(work=Path(work), report=report, quicklook=quick, passed=passed)
