"""The numbers that justify a plan (summary.json and the table `sfap plan` prints)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from . import exposure as ex
from .camera import Orientation
from .geo import LocalFrame
from .plan import Summary
from .spec import MissionSpec

if TYPE_CHECKING:
    from .mission_builder import BuiltMission, PassPlan


def summarize(
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    area_m2: float,
    alt_agl_m: float,
    speed_m_s: float,
    nadir: PassPlan,
    passes: list[PassPlan],
    built: BuiltMission,
    warnings: tuple[str, ...],
    true_north_grid_deg: float,
    terrain: dict[str, object] | None = None,
) -> Summary:
    camera = spec.camera
    footprint = camera.footprint(alt_agl_m, spec.orientation)
    landscape = spec.orientation is Orientation.LANDSCAPE
    gsd_along = camera.gsd_y_cm(alt_agl_m) if landscape else camera.gsd_x_cm(alt_agl_m)
    gsd_across = camera.gsd_x_cm(alt_agl_m) if landscape else camera.gsd_y_cm(alt_agl_m)
    air_base = nadir.trigger_distance_m
    max_trigger = min(
        ex.max_speed_for_trigger_m_s(p.trigger_distance_m, camera.min_trigger_interval_s) for p in passes
    )
    max_blur = (
        ex.max_speed_for_blur_m_s(min(gsd_along, gsd_across), camera.shutter_s, spec.survey.max_blur_px)
        if camera.shutter_s is not None
        else None
    )
    max_speed = min(max_trigger, max_blur) if max_blur is not None else max_trigger
    interval = ex.exposure_interval_s(air_base, speed_m_s)
    return Summary(
        name=spec.name,
        area_m2=area_m2,
        camera_id=camera.id,
        orientation=spec.orientation.value,
        gsd_cm=camera.gsd_cm(alt_agl_m),
        gsd_along_cm=gsd_along,
        gsd_across_cm=gsd_across,
        altitude_agl_m=alt_agl_m,
        scale_number=camera.scale_number(alt_agl_m),
        footprint_along_m=footprint.along_m,
        footprint_across_m=footprint.across_m,
        front_overlap_pct=spec.survey.front_overlap_pct,
        side_overlap_pct=spec.survey.side_overlap_pct,
        air_base_m=air_base,
        line_spacing_m=nadir.line_spacing_m,
        trigger_distance_m=air_base,
        exposure_interval_s=interval,
        speed_m_s=speed_m_s,
        max_speed_m_s=max_speed,
        max_speed_trigger_m_s=max_trigger,
        max_speed_blur_m_s=max_blur,
        base_height_ratio=ex.base_height_ratio(air_base, alt_agl_m),
        intersection_angle_deg=ex.intersection_angle_deg(air_base, alt_agl_m),
        depth_precision_m=ex.depth_precision_m(camera, air_base, alt_agl_m),
        direction_deg=(nadir.direction_deg - true_north_grid_deg) % 180.0,
        pass_count=len(passes),
        line_count=sum(len({s.row for s in p.segments}) for p in passes),
        photo_count=len(built.stations),
        flight_distance_m=built.flight_distance_m,
        flight_time_s=built.flight_time_s,
        item_count=len(built.mission.items),
        crs=f"EPSG:{frame.epsg}" if frame.epsg else frame.crs.to_string(),
        warnings=warnings,
        terrain=terrain,
    )
