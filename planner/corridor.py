"""Corridor surveys: a centre line (a road, a river, a pipeline) and a width.

The corridor is every point within ``corridor_width_m / 2`` of the centre line (flat ends at its
first and last point, round on the outside of bends). It is flown as lines parallel to the
centre line:

1. The centre line is simplified (Douglas-Peucker, tolerance a tenth of the width and at most
   a fifth of the frame's width) so that each kept segment is flown as one straight run; the
   lines must then cover the corridor's half-width plus that tolerance.
2. Lines: the fewest n at the side-overlap spacing S whose frames span that width,
   ``(n - 1) S + across >= width + 2 tolerance``, at fixed offsets from the centre line
   (centred), the same offsets on every segment, so line k is one polyline along the whole
   corridor (a width at or below one frame: a single line along the centre).
3. Segments: the corridor is cut at the bisector of each bend into pieces, one per segment
   (at a bend each side of the bisector is nearer its own segment). Each piece is laid out as a
   block in its segment's frame (planner.lines.layout_pass with the corridor's fixed line
   offsets): each line's photos span the piece where its band of the corridor lies, so on the
   outside of a bend the runs reach past the bisector as far as the corridor does (no gap),
   and on the inside they stop where the corridor's edge crosses the bisector (no photos over
   the neighbour's piece but the end stations that give the bend its stereo views); exclusions,
   fill runs for gaps and stereo at the edges are a block's (planner.lines).
4. Order: line 0 along the corridor, line 1 back, and so on; within a piece each run is flown in
   the direction its neighbour ends nearest (planner.mission_builder, one pass per run, whose
   DO_SET_CAM_TRIGG_DIST is set for that run's own spacing).
5. Terrain, speed checks, fixed-wing turns and the summary are a block's (planner.survey_steps).

The geometry of steps 1-3 is planner.corridor_layout.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon

from . import exposure as ex
from . import survey_steps as steps
from . import trigger as trig
from .area import load_centreline, load_polygons, polygonal
from .corridor_layout import CorridorLayout, bearing_deg, check_simple, corridor_layout, corridor_polygon
from .coverage import ViewShares, boundary_points, grid_points, view_counts
from .errors import AreaError, SpecError
from .footprint import near_far_gsd_cm
from .geo import LocalFrame
from .kinds import PassKind
from .lines import Segment, layout_pass
from .mission_builder import BuiltMission, PassPlan
from .plan import FlightPass, SurveyPlan
from .spec import MissionSpec, TriggerMode

log = logging.getLogger(__name__)


def plan_corridor(spec: MissionSpec) -> SurveyPlan:
    """Plan a corridor survey (module docstring). Raises SfapError subclasses with the fix."""
    survey = spec.survey
    width = spec.corridor_width_m
    assert width is not None
    where = str(spec.source)
    if survey.crosshatch or survey.oblique:
        raise SpecError(
            f"{where}: a corridor is flown as nadir lines along its centre line; remove "
            f"{'crosshatch' if survey.crosshatch else '[[survey.oblique]]'} from [survey] (corridor "
            f"obliques are not planned: plan them as a block over the corridor's polygon)"
        )
    if survey.direction_deg is not None:
        raise SpecError(
            f'{where}: a corridor\'s lines follow its centre line; remove direction_deg (or "auto")'
        )
    points = load_centreline(spec.area_path)
    lons, lats = zip(*points, strict=True)
    frame = LocalFrame.utm_for(float(np.mean(lons)), float(np.mean(lats)))
    if max(lons) - min(lons) > 180.0:
        raise AreaError(
            f"{spec.area_path}: the centre line crosses the antimeridian; split it at 180 degrees"
        )
    x, y = frame.to_xy(np.asarray(lons), np.asarray(lats))
    centre_xy = LineString(np.column_stack([x, y]))
    check_simple(centre_xy, frame, str(spec.area_path))

    exclusions = [p for path in spec.exclude_paths for p in load_polygons(path)]
    corridor_lonlat = frame.geometry_to_lonlat(corridor_polygon(centre_xy, width))
    site = steps.project_area(spec, [corridor_lonlat], exclusions, what="corridor", frame=frame)
    area_xy = site.area_xy
    alt_agl_m, gsd_cm = steps.flying_height(spec)

    def default_home() -> tuple[float, float]:
        c0 = centre_xy.coords[0]
        inside = area_xy.contains(shapely.Point(c0))
        return (float(c0[0]), float(c0[1])) if inside else steps.default_home_xy(area_xy)

    home, home_xy = steps.home_position(spec, site, near=area_xy, default_xy=default_home, what="corridor")
    blocked_xy = steps.blocked_xy(spec, site.zones_xy)
    dem = steps.read_dem(spec, site.area_lonlat, home) if spec.terrain is not None else None
    warnings: list[str] = []

    def attempt(scale: float) -> _Attempt:
        warnings.clear()
        laid = _lay_out(spec, centre_xy, area_xy, blocked_xy, alt_agl_m, gsd_cm, scale, warnings)
        built = steps.build(
            spec, site, home, home_xy, alt_agl_m=alt_agl_m, speed_m_s=laid.speed_m_s, passes=laid.run_passes
        )
        # Stations by piece (its frame, its lines) for the terrain's overlap figures.
        run_of_station = built.stations.pass_index.copy()
        built = dataclasses.replace(
            built,
            stations=dataclasses.replace(built.stations, pass_index=laid.piece_of_run[run_of_station]),
        )
        return _Attempt(runs=laid, built=built, run_of_station=run_of_station)

    done, fit = steps.fit_to_terrain(
        spec, site, home, home_xy, alt_agl_m=alt_agl_m, dem=dem, attempt=attempt, warnings=warnings
    )
    laid = done.runs
    # One pass for the writers: every run of the corridor, numbered by corridor line.
    line_of_run = laid.line_of_run
    lines = tuple(
        dataclasses.replace(line, pass_index=0, line_index=int(line_of_run[pp.index]))
        for pp in laid.run_passes
        for line in fit.built.lines[pp.index]
    )
    first = laid.piece_passes[0]
    true_north_grid = site.true_north_grid_deg
    passes = (
        FlightPass(
            index=0,
            kind=PassKind.NADIR,
            name="corridor",
            direction_deg=(first.direction_deg - true_north_grid) % 180.0,
            tilt_deg=0.0,
            look_heading_deg=None,
            alt_agl_m=alt_agl_m,
            line_spacing_m=first.line_spacing_m,
            trigger_distance_m=first.trigger_distance_m,
            lines=lines,
            near_gsd_cm=first.near_gsd_cm,
            far_gsd_cm=first.far_gsd_cm,
        ),
    )
    layout = laid.layout
    corridor_info: dict[str, object] = {
        "width_m": width,
        "centre_line_length_m": float(centre_xy.length),
        "segment_count": len(layout.pieces_xy),
        "line_offsets_m": list(layout.line_offsets_m),
        "single_line": len(layout.line_offsets_m) == 1,
    }
    n_stations = len(fit.built.stations)
    return steps.finish_plan(
        spec,
        site,
        done,
        fit,
        home_xy,
        alt_agl_m=alt_agl_m,
        flight_passes=passes,
        warnings=warnings,
        what="corridor",
        frames="frames",
        logger=log,
        stations_replaced={
            "pass_index": np.zeros(n_stations, np.int32),
            "line_index": line_of_run[done.run_of_station],
        },
        summary_replaced={
            "pass_count": 1,
            "line_count": int(line_of_run.max()) + 1 if len(line_of_run) else 0,
            "corridor": corridor_info,
        },
    )


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Runs:
    """The corridor laid out at one footprint scale."""

    layout: CorridorLayout
    run_passes: list[PassPlan]  # one per run, in flight order
    piece_passes: list[PassPlan]  # one per piece (all its runs): what terrain overlaps judge
    speed_m_s: float
    views: ViewShares
    line_of_run: np.ndarray  # per run: its corridor line number
    piece_of_run: np.ndarray  # per run: its piece


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Attempt:
    """The runs built into a mission whose stations are numbered by piece."""

    runs: _Runs
    built: BuiltMission
    run_of_station: np.ndarray  # per station: its run

    # What planner.survey_steps reads of an attempt: the pieces judge the terrain's overlaps.
    terrain_passes = property(lambda self: self.runs.piece_passes)
    speed_m_s = property(lambda self: self.runs.speed_m_s)
    views = property(lambda self: self.runs.views)


def _lay_out(
    spec: MissionSpec,
    centre_xy: LineString,
    area_xy: Polygon | MultiPolygon,
    blocked_xy: shapely.Geometry | None,
    alt_agl_m: float,
    gsd_cm: float,
    scale: float,
    warnings: list[str],
) -> _Runs:
    """Runs of every piece: the layout, one PassPlan per run in flight order, one per piece (all
    its runs), the speed, the corridor's view shares, and per run its corridor line number and
    its piece."""

    survey, camera = spec.survey, spec.camera
    assert spec.corridor_width_m is not None
    hover = survey.trigger is TriggerMode.HOVER
    up = ex.up_bearing_deg(0.0, spec.orientation)
    rect = ex.frame_rectangle(camera, alt_agl_m, 0.0, up, 0.0).scaled(scale)
    trigger_m = ex.air_base_m(rect.along_m, survey.front_overlap_pct)
    spacing_m = ex.air_base_m(rect.across_m, survey.side_overlap_pct)
    pdef = steps.PassDef(
        kind=PassKind.NADIR, name="corridor", direction_deg=0.0, tilt_deg=0.0, look_heading_deg=None,
        front_overlap_pct=survey.front_overlap_pct, side_overlap_pct=survey.side_overlap_pct,
    )  # fmt: skip
    speed_m_s = steps.check_speed(spec, pdef, trigger_m, alt_agl_m, survey.speed_m_s, warnings)
    layout = corridor_layout(centre_xy, spec.corridor_width_m, rect.across_m, spacing_m)
    offsets = layout.line_offsets_m
    n_lines = len(offsets)
    coords = np.asarray(layout.flown_xy.coords)
    step_m = trigger_m if hover else trig.station_step_m(trigger_m, speed_m_s)
    near_gsd, far_gsd = near_far_gsd_cm(camera, alt_agl_m, 0.0)

    def pass_plan(index: int, name: str, bearing: float, segments: tuple[Segment, ...]) -> PassPlan:
        return PassPlan(
            index=index, kind=PassKind.NADIR, name=name, direction_deg=bearing, tilt_deg=0.0,
            look_heading_deg=None, rect=rect, trigger_distance_m=trigger_m, line_spacing_m=spacing_m,
            segments=segments, near_gsd_cm=near_gsd, far_gsd_cm=far_gsd, centre_gsd_cm=gsd_cm,
            front_overlap_pct=survey.front_overlap_pct, side_overlap_pct=survey.side_overlap_pct,
        )  # fmt: skip

    bearings: list[float] = []
    firsts: list[float] = []
    piece_segments: list[tuple[Segment, ...]] = []
    for i, piece in enumerate(layout.pieces_xy):
        bearing = bearing_deg(coords[i], coords[i + 1])
        piece_area = polygonal(piece.intersection(area_xy))
        segments: tuple[Segment, ...] = ()
        _, vc_arr = ex.to_pass_frame(coords[i : i + 1, 0], coords[i : i + 1, 1], bearing)
        v_first = float(vc_arr[0]) + offsets[0]
        if not piece_area.is_empty and piece_area.area > 1e-6:
            area_uv = ex.geometry_to_pass_frame(piece_area, bearing)
            if not area_uv.is_valid:  # rounding in the rotation of a sliver of a bend
                area_uv = polygonal(shapely.make_valid(area_uv))
            blocked_uv = ex.geometry_to_pass_frame(blocked_xy, bearing) if blocked_xy is not None else None
            lay = layout_pass(
                area_uv, blocked_uv, rect, step_m, spacing_m, first_line_v_m=v_first, line_count=n_lines
            )
            segments = lay.segments if hover else trig.split_for_trigger(lay.segments, speed_m_s)
            if lay.uncovered_m2 > 0:
                warnings.append(
                    f"corridor segment {i + 1}: {lay.uncovered_m2:.0f} m2 beside exclusion zones cannot be "
                    f"seen without flying over them"
                )
        bearings.append(bearing)
        firsts.append(v_first)
        piece_segments.append(segments)

    # Three views where the forward overlap gives them along a line, else two (stereo).
    need = 3 if 3.0 * trigger_m <= rect.along_m + 1e-9 else 2
    piece_segments = trim_end_stations(
        area_xy, bearings, piece_segments, rect, min(trigger_m, spacing_m), need, firsts, spacing_m, n_lines
    )
    piece_passes: list[PassPlan] = []
    # per piece: corridor line -> rows (each a tuple of segments), fill rows flagged
    rows_of_piece: list[dict[int, list[tuple[bool, tuple[Segment, ...]]]]] = []
    for i, segments in enumerate(piece_segments):
        by_line: dict[int, list[tuple[bool, tuple[Segment, ...]]]] = {}
        rows: dict[int, list[Segment]] = {}
        for seg in segments:
            rows.setdefault(seg.row, []).append(seg)
        for row in sorted(rows, key=lambda r: rows[r][0].v_m):
            segs = tuple(sorted(rows[row], key=lambda s: s.u_first_m))
            k_real = (segs[0].v_m - firsts[i]) / spacing_m
            k = min(max(round(k_real), 0), n_lines - 1)
            fill = abs(k_real - round(k_real)) > 1e-6 or not 0 <= round(k_real) < n_lines
            by_line.setdefault(k, []).append((fill, segs))
        piece_passes.append(pass_plan(i, f"corridor segment {i + 1}", bearings[i], segments))
        rows_of_piece.append(by_line)

    run_passes: list[PassPlan] = []
    line_of_run: list[int] = []
    piece_of_run: list[int] = []
    fill_numbers: dict[tuple[int, int], int] = {}
    n_pieces = len(layout.pieces_xy)
    for k in range(n_lines):
        order = range(n_pieces) if k % 2 == 0 else range(n_pieces - 1, -1, -1)
        for i in order:
            for j, (fill, segs) in enumerate(rows_of_piece[i].get(k, [])):
                number = k
                if fill:
                    number = fill_numbers.setdefault((i, k * 1000 + j), n_lines + len(fill_numbers))
                run_passes.append(
                    pass_plan(
                        len(run_passes), f"corridor line {number + 1}", piece_passes[i].direction_deg, segs
                    )
                )
                line_of_run.append(number)
                piece_of_run.append(i)
    if not run_passes:
        raise SpecError(f"{spec.source}: no line of the corridor can be flown (the exclusions cover it)")
    views = corridor_views(area_xy, piece_passes, rect, min(trigger_m, spacing_m))
    return _Runs(
        layout=layout, run_passes=run_passes, piece_passes=piece_passes, speed_m_s=speed_m_s, views=views,
        line_of_run=np.asarray(line_of_run, np.int32), piece_of_run=np.asarray(piece_of_run, np.int32),
    )  # fmt: skip


def _sample(area_xy: Polygon | MultiPolygon, base_m: float) -> tuple[np.ndarray, float]:
    """Points of the corridor: a jittered grid (cells of an eighth of ``base_m``) and its edges."""
    points, cell = grid_points(area_xy, base_m / 8.0)
    return np.vstack([points, boundary_points(area_xy, max(cell, 0.5))]), cell


def _near(
    points: np.ndarray, bearing: float, segments: tuple[Segment, ...], reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the points within ``reach`` of the segments' stations, and those points in the
    segments' pass frame."""
    pu, pv = ex.to_pass_frame(points[:, 0], points[:, 1], bearing)
    u = np.array([[s.u_first_m, s.u_last_m] for s in segments])
    v = np.array([s.v_m for s in segments])
    near = (
        (pu >= u.min() - reach) & (pu <= u.max() + reach) & (pv >= v.min() - reach) & (pv <= v.max() + reach)
    )
    idx = np.flatnonzero(near)
    return idx, np.column_stack([pu[idx], pv[idx]])


def trim_end_stations(
    area_xy: Polygon | MultiPolygon,
    bearings: list[float],
    piece_segments: list[tuple[Segment, ...]],
    rect: ex.FrameRectangle,
    base_m: float,
    need: int,
    line_v_first_m: list[float],
    spacing_m: float,
    n_lines: int,
) -> list[tuple[Segment, ...]]:
    """Drop the end stations of runs that only repeat what the same corridor line already sees
    from its run on the neighbouring segment (at a bend both runs of a line reach over the
    bisector). A station of line k goes only if every sampled point of the corridor in its frame
    and in line k's band (half a spacing either side, open on the corridor's outer sides) keeps
    at least ``need`` views from line k's frames; the other lines' frames do not count, so the
    side overlap stays as planned. Fill runs and the ends where a run continues another (split
    runs) stay. ``line_v_first_m``: per piece, v of line 0 in the piece's frame."""
    points, _ = _sample(area_xy, base_m)
    reach = math.hypot(rect.along_m, rect.across_m)

    def line_of(i: int, seg: Segment) -> int | None:
        k_real = (seg.v_m - line_v_first_m[i]) / spacing_m
        k = round(k_real)
        return k if abs(k_real - k) < 1e-6 and 0 <= k < n_lines and not seg.fill else None

    counts = np.zeros((n_lines, len(points)), np.int64)
    local: list[tuple[np.ndarray, np.ndarray]] = []
    for i, (bearing, segments) in enumerate(zip(bearings, piece_segments, strict=True)):
        if not segments:
            local.append((np.zeros(0, np.intp), np.zeros((0, 2))))
            continue
        idx, uv = _near(points, bearing, segments, reach)
        for k in range(n_lines):
            of_k = tuple(s for s in segments if line_of(i, s) == k)
            if of_k:
                counts[k, idx] += view_counts(uv, of_k, rect)
        local.append((idx, uv))
    out: list[tuple[Segment, ...]] = []
    for i, ((idx, uv), segments) in enumerate(zip(local, piece_segments, strict=True)):
        kept: list[Segment] = []
        for seg in segments:
            line = line_of(i, seg)
            if line is None:
                kept.append(seg)
                continue
            k = line
            dv = uv[:, 1] - seg.v_m
            band = (dv >= (-math.inf if k == 0 else -spacing_m / 2.0)) & (
                dv <= (math.inf if k == n_lines - 1 else spacing_m / 2.0)
            )
            band &= (dv >= rect.v_min_m) & (dv <= rect.v_max_m)
            for low_end in (True, False):
                if seg.join_lo if low_end else seg.join_hi:
                    continue
                while seg.count > 1:
                    du = uv[:, 0] - (seg.u_first_m if low_end else seg.u_last_m)
                    seen = idx[band & (du >= rect.u_min_m) & (du <= rect.u_max_m)]
                    if np.any(counts[k, seen] - 1 < need):
                        break
                    counts[k, seen] -= 1
                    seg = dataclasses.replace(
                        seg,
                        u_first_m=seg.u_first_m + (seg.spacing_m if low_end else 0.0),
                        count=seg.count - 1,
                    )
            kept.append(seg)
        out.append(tuple(kept))
    return out


def corridor_views(
    area_xy: Polygon | MultiPolygon, pieces: list[PassPlan], rect: ex.FrameRectangle, base_m: float
) -> ViewShares:
    """Shares of the corridor seen by >= 1, 2, 3 frames, counting the frames of every piece (a
    bend is seen by both its segments' frames): a jittered grid and the corridor's edges."""
    points, cell = _sample(area_xy, base_m)
    counts = np.zeros(len(points), np.int64)
    reach = math.hypot(rect.along_m, rect.across_m)
    for pp in pieces:
        if not pp.segments:
            continue
        idx, uv = _near(points, pp.direction_deg, pp.segments, reach)
        counts[idx] += view_counts(uv, pp.segments, rect)
    n = max(1, len(counts))
    return ViewShares(
        seen_1_pct=100.0 * np.count_nonzero(counts >= 1) / n,
        seen_2_pct=100.0 * np.count_nonzero(counts >= 2) / n,
        seen_3_pct=100.0 * np.count_nonzero(counts >= 3) / n,
        cell_m=cell,
    )
