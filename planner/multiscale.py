"""Multi-scale blocks: further nadir passes over the same area at other heights.

The textbook names multi-scale images (two flying heights, e.g. 105 m and 190 m) among the remedies
for the doming effect of self-calibrated SfM blocks (James and Robson 2014; REFERENCES.md). Each
``[[survey.scale]]`` of the spec adds one nadir pass, laid out like the main nadir pass (same line
direction, edge coverage and exclusions) but with the frame, air base and line spacing of its own
height and overlaps. The passes are tagged by their index (``pass`` in stations.geojson,
footprints.geojson and flight_lines.geojson), so the check and the hand-off can tell them apart.

``scale_flight = "one_mission"`` flies them after the main passes in the same mission (the vehicle
climbs or descends between them; the flight time counts it); ``"sorties"`` makes every pass height
its own set of sorties (planner.sorties).
"""

from __future__ import annotations

from typing import Any

from .errors import SpecError
from .kinds import PassKind
from .plan import SurveyPlan
from .spec import MissionSpec


def scale_alt_agl_m(spec: MissionSpec, index: int) -> float:
    """Height above ground of ``spec.survey.scales[index]``, checked against the vehicle limit."""
    scale = spec.survey.scales[index]
    if scale.altitude_agl_m is not None:
        alt_m = scale.altitude_agl_m
    else:
        assert scale.gsd_cm is not None
        alt_m = spec.camera.height_for_gsd_m(scale.gsd_cm)
    if alt_m > spec.vehicle.max_alt_agl_m + 1e-9:
        raise SpecError(
            f"{spec.source}: [[survey.scale]] {index + 1} needs a flying height of {alt_m:.1f} m above "
            f"ground, above the vehicle limit max_alt_agl_m = {spec.vehicle.max_alt_agl_m:g} m; ask "
            f"for a finer gsd_cm or a lower altitude_agl_m there, or raise the limit"
        )
    return alt_m


#: Two nadir passes whose heights differ by less than this share are the same pass flown twice.
SAME_HEIGHT_SHARE = 0.05


def scale_pass_defs(spec: MissionSpec, direction_deg: float, main_alt_agl_m: float) -> list[dict[str, Any]]:
    """The fields of one extra nadir pass per ``[[survey.scale]]`` (grid bearing ``direction_deg``,
    that of the main nadir lines). A scale at the main pass's height, or another scale's (within
    SAME_HEIGHT_SHARE), is refused: it would fly the same photos twice."""
    survey = spec.survey
    out = []
    heights = [("the main pass", main_alt_agl_m)]
    for k, scale in enumerate(survey.scales):
        alt_m = scale_alt_agl_m(spec, k)
        for what, other in heights:
            if abs(alt_m - other) < SAME_HEIGHT_SHARE * max(alt_m, other):
                gsd = spec.camera.gsd_cm(alt_m)
                raise SpecError(
                    f"{spec.source}: [[survey.scale]] {k + 1} flies at {alt_m:.1f} m above ground "
                    f"(GSD {gsd:.2f} cm), the height of {what} ({other:.1f} m): it would take the same "
                    f"photos twice; give it a gsd_cm or altitude_agl_m at least "
                    f"{100 * SAME_HEIGHT_SHARE:g} % away, or remove it"
                )
        heights.append((f"[[survey.scale]] {k + 1}", alt_m))
        out.append(
            {
                "kind": PassKind.NADIR,
                "name": f"nadir at {alt_m:.0f} m (scale {k + 1})",
                "direction_deg": direction_deg % 180.0,
                "tilt_deg": 0.0,
                "look_heading_deg": None,
                "front_overlap_pct": (
                    scale.front_overlap_pct
                    if scale.front_overlap_pct is not None
                    else survey.front_overlap_pct
                ),
                "side_overlap_pct": (
                    scale.side_overlap_pct if scale.side_overlap_pct is not None else survey.side_overlap_pct
                ),
                "alt_agl_m": alt_m,
            }
        )
    return out


def pass_summaries(plan: SurveyPlan) -> list[dict[str, object]]:
    """Per pass: height, GSD, spacing, trigger distance, lines and photos (summary.json "scales")."""
    out: list[dict[str, object]] = []
    for p in plan.passes:
        mask = plan.stations.pass_index == p.index
        out.append(
            {
                "pass": p.index,
                "name": p.name,
                "kind": p.kind.value,
                "alt_agl_m": p.alt_agl_m,
                "gsd_cm": plan.camera.gsd_cm(p.alt_agl_m) if p.tilt_deg == 0 else p.near_gsd_cm,
                "line_spacing_m": p.line_spacing_m,
                "trigger_distance_m": p.trigger_distance_m,
                "line_count": len({line.line_index for line in p.lines}),
                "photo_count": int(mask.sum()),
                "camera_on_m": float(sum(line.length_m for line in p.lines)),
            }
        )
    return out
