"""Plans of part of a plan's lines (a sortie, what is left after a flight cut short): the lines
chosen are built into a mission, and fitted to the terrain, as the whole plan was
(planner.sorties, planner.resume). What a sortie or a resume plan chooses is theirs; how a choice
of lines becomes a plan of its own is here."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from .errors import PlanningError
from .exposure import from_pass_frame
from .fixed_wing import fixed_wing_for
from .lines import Segment
from .mission_builder import BuiltMission, PassPlan, build_mission
from .plan import PlanLayout, SurveyPlan


def plan_layout(plan: SurveyPlan) -> PlanLayout:
    """The layout the plan was built from (its passes, height, speed, DEM); refused for a plan
    that holds none."""
    if plan.layout is None:
        raise PlanningError("this plan holds no layout to split: plan it again from its mission spec")
    return plan.layout


def build_part(plan: SurveyPlan, layout: PlanLayout, pass_plans: list[PassPlan]) -> BuiltMission:
    """The mission of some lines of ``plan``, built (and fitted to the terrain) as the plan was."""
    spec = layout.spec
    built = build_mission(
        spec=spec, frame=plan.frame, home=plan.home, home_xy=plan.home_xy_m, alt_agl_m=layout.alt_agl_m,
        speed_m_s=layout.speed_m_s, passes=pass_plans, zones_xy=plan.exclusions_xy,
        true_north_grid_deg=layout.true_north_grid_deg,
        fixed_wing=fixed_wing_for(spec, layout.speed_m_s, layout.true_north_grid_deg),
    )  # fmt: skip
    if spec.terrain is not None and layout.dem is not None:
        from .terrain_follow import apply_terrain

        built, _, _ = apply_terrain(
            built, dem=layout.dem, terrain=spec.terrain, frame=plan.frame, home=plan.home,
            home_xy=plan.home_xy_m, alt_agl_m=layout.alt_agl_m, speed_m_s=layout.speed_m_s,
            max_alt_agl_m=spec.vehicle.max_alt_agl_m, passes=pass_plans, camera=spec.camera,
            footprint_scale=layout.footprint_scale,
        )  # fmt: skip
    return built


def part_plan(
    plan: SurveyPlan,
    layout: PlanLayout,
    built: BuiltMission,
    name: str,
    pass_plans: list[PassPlan],
    *,
    sortie: bool = False,
) -> SurveyPlan:
    """A plan of its own for part of ``plan``: same area and passes, this mission's lines,
    stations, path and flight figures."""
    from .summary import limit_warnings

    passes = tuple(dataclasses.replace(p, lines=built.lines.get(p.index, ())) for p in plan.passes)
    vehicle = layout.spec.vehicle
    warnings = tuple(
        limit_warnings(
            vehicle=vehicle,
            item_count=len(built.mission.items),
            flight_time_s=built.flight_time_s,
            sortie=sortie,
        )
    )
    summary = dataclasses.replace(
        plan.summary,
        name=name,
        line_count=sum(len({line.line_index for line in p.lines}) for p in passes),
        photo_count=len(built.stations),
        flight_distance_m=built.flight_distance_m,
        flight_time_s=built.flight_time_s,
        item_count=len(built.mission.items),
        warnings=warnings,
    )
    mission = dataclasses.replace(built.mission, metadata={**built.mission.metadata, "name": name})
    return dataclasses.replace(
        plan,
        name=name,
        passes=passes,
        stations=built.stations,
        path_xy_m=built.path_xy_m,
        path_lonlat_deg=built.path_lonlat_deg,
        mission=mission,
        home=mission.home,
        summary=summary,
        warnings=warnings,
        layout=dataclasses.replace(layout, pass_plans=tuple(pass_plans)),
    )


def segment_xy(pp: PassPlan, seg: Segment) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The stations of one run in the plan's frame (x east, y north, metres)."""
    u = seg.u_first_m + np.arange(seg.count) * seg.spacing_m
    x, y = from_pass_frame(u, np.full_like(u, seg.v_m), pp.direction_deg)
    return np.asarray(x, float), np.asarray(y, float)


def station_keys(
    pass_index: NDArray[np.int32], x: NDArray[np.float64], y: NDArray[np.float64]
) -> list[tuple[int, float, float]]:
    """Stations as (pass, x, y rounded to the centimetre): the same station in two plans."""
    return [
        (int(p), round(float(a), 2), round(float(b), 2)) for p, a, b in zip(pass_index, x, y, strict=True)
    ]
