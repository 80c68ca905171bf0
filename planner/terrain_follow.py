"""Terrain following: waypoint altitudes that keep the height above ground, and the GSD and
overlap spread over the terrain.

With a DEM the planned path is sampled every ``sample_spacing_m``. Following the terrain, the
target altitude is ground + height above ground; the altitude profile flown is the lowest one at
or above the target whose climbs and descents the vehicle can fly at its speed
(``max_climb_rate_m_s``, ``max_descent_rate_m_s``): a forward pass bounds descents, a backward
pass starts climbs early enough. Waypoints are then added where a straight leg between the
existing ones would depart from that profile by more than ``tolerance_m`` (recursive split at
the worst sample, as Douglas-Peucker does). Altitudes stay relative to home (barometric on the
vehicle), home's elevation taken from the DEM.

Without following (constant altitude above home), the path is only checked for ground
clearance, and the spread is reported: higher ground is closer to the camera, so its GSD is
finer and its overlap lower (Aber et al. 2019, ch. 3).

Stations keep their horizontal positions (distance triggering is horizontal); their altitude
is the flown profile at their distance along the path, and their footprint and GSD follow their
height above the ground below them.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray

from .camera import Camera
from .errors import PlanningError
from .flight_path import PathPoint, Role
from .footprint import cast_on_dem, image_grid_mm
from .geo import LocalFrame
from .mission import HomePosition
from .mission_builder import BuiltMission, PassPlan
from .plan import Stations
from .spec import TerrainSpec
from .terrain import Dem

log = logging.getLogger(__name__)

#: A flight closer to the ground than this, anywhere on the path, is refused.
MIN_CLEARANCE_M = 5.0


@dataclass(frozen=True, kw_only=True)
class CastOverlap:
    """The smallest overlap of neighbouring frames of one pass, cast on the DEM (percent;
    negative: a gap), and where it is (the local frame's x, y: the middle of the two cameras)."""

    pass_index: int
    front_pct: float
    front_xy: tuple[float, float] | None
    side_pct: float
    side_xy: tuple[float, float] | None


@dataclass(frozen=True, kw_only=True)
class TerrainSummary:
    """How the terrain shapes the plan (summary.json's ``terrain``)."""

    dem: str
    follow: bool
    home_ground_amsl_m: float
    ground_min_amsl_m: float
    ground_max_amsl_m: float
    station_alt_agl_min_m: float
    station_alt_agl_max_m: float
    gsd_min_cm: float
    gsd_max_cm: float
    front_overlap_min_pct: float
    side_overlap_min_pct: float
    path_alt_agl_min_m: float
    path_alt_agl_max_m: float
    alt_rel_home_max_m: float
    waypoints_added: int
    #: The frame size lines and triggers were spaced for, relative to flat ground (1: flat).
    footprint_scale: float
    #: The smallest height above the highest ground a nadir frame sees, over the planned height.
    footprint_scale_min: float
    #: Where the smallest forward and side overlaps are (the middle of the two cameras; None:
    #: no pair of frames, or a plan from before these were written).
    front_overlap_min_lon_deg: float | None = None
    front_overlap_min_lat_deg: float | None = None
    side_overlap_min_lon_deg: float | None = None
    side_overlap_min_lat_deg: float | None = None

    def as_dict(self) -> dict[str, object]:
        return dataclasses.asdict(self)


def rate_limited_profile(
    s_m: NDArray[np.float64],
    target_m: NDArray[np.float64],
    speed_m_s: float,
    max_climb_rate_m_s: float,
    max_descent_rate_m_s: float,
) -> NDArray[np.float64]:
    """The lowest altitude profile >= ``target_m`` whose slopes the vehicle can fly: climbing at
    most ``max_climb_rate_m_s`` and descending at most ``max_descent_rate_m_s`` at ``speed_m_s``
    over the distance ``s_m`` (ascending)."""
    a = target_m.astype(float).copy()
    ds = np.diff(s_m)
    down = max_descent_rate_m_s / speed_m_s * ds
    up = max_climb_rate_m_s / speed_m_s * ds
    for k in range(1, len(a)):  # descents no steeper than allowed
        a[k] = max(a[k], a[k - 1] - down[k - 1])
    for k in range(len(a) - 2, -1, -1):  # climbs started early enough
        a[k] = max(a[k], a[k + 1] - up[k])
    return a


def _split_leg(s: NDArray[np.float64], a: NDArray[np.float64], tolerance_m: float) -> list[int]:
    """Indices (inside the leg's samples) where waypoints keep a straight-line interpolation
    within ``tolerance_m`` of the profile ``a`` (first and last samples are the leg's ends)."""
    out: list[int] = []

    def recurse(i: int, j: int) -> None:
        if j - i < 2:
            return
        t = (s[i + 1 : j] - s[i]) / (s[j] - s[i]) if s[j] > s[i] else np.zeros(j - i - 1)
        line = a[i] + t * (a[j] - a[i])
        dev = np.abs(line - a[i + 1 : j])
        k = int(np.argmax(dev))
        if dev[k] > tolerance_m:
            m = i + 1 + k
            recurse(i, m)
            out.append(m)
            recurse(m, j)

    recurse(0, len(s) - 1)
    return out


def apply_terrain(
    built: BuiltMission,
    *,
    dem: Dem,
    terrain: TerrainSpec,
    frame: LocalFrame,
    home: HomePosition,
    home_xy: tuple[float, float],
    alt_agl_m: float,
    speed_m_s: float,
    max_alt_agl_m: float,
    passes: list[PassPlan],
    camera: Camera,
    footprint_scale: float = 1.0,
) -> tuple[BuiltMission, HomePosition, TerrainSummary]:
    """Waypoint altitudes, extra waypoints and station heights over the DEM (module docstring):
    the flight path reshaped, then its items emitted again (planner.mission_items)."""
    flat = built.path
    along = flat.distance_along_m()
    track = flat.horizontal()  # the points that end legs; the samples are taken along them
    path = built.path_xy_m
    path_s = np.asarray([along[k] for k in track], float)
    home_ground = float(dem.elevation_at(np.array([home_xy[0]]), np.array([home_xy[1]]), frame)[0])

    # Sample every leg of the path (both ends included), remembering where legs start.
    s_parts, x_parts, y_parts = [], [], []
    for k in range(len(path) - 1):
        (x0, y0), (x1, y1) = path[k], path[k + 1]
        length = path_s[k + 1] - path_s[k]
        n = max(1, math.ceil(length / terrain.sample_spacing_m))
        t = np.linspace(0.0, 1.0, n + 1)[:-1] if k < len(path) - 2 else np.linspace(0.0, 1.0, n + 1)
        s_parts.append(path_s[k] + t * length)
        x_parts.append(x0 + t * (x1 - x0))
        y_parts.append(y0 + t * (y1 - y0))
        s = np.concatenate(s_parts)
    x = np.concatenate(x_parts)
    y = np.concatenate(y_parts)
    ground = dem.elevation_at(x, y, frame)

    if terrain.follow:
        profile = rate_limited_profile(
            s, ground + alt_agl_m, speed_m_s, terrain.max_climb_rate_m_s, terrain.max_descent_rate_m_s
        )
    else:
        profile = np.full_like(s, home_ground + alt_agl_m)

    # Waypoints: the path points (their profile altitude) plus the splits of each leg.
    point_sample = np.searchsorted(s, path_s - 1e-9)
    point_sample[-1] = len(s) - 1
    extra_by_leg: dict[int, list[int]] = {}
    if terrain.follow:
        for k in range(len(path) - 1):
            i, j = int(point_sample[k]), int(point_sample[k + 1])
            splits = _split_leg(s[i : j + 1], profile[i : j + 1], terrain.tolerance_m)
            if splits:
                extra_by_leg[k] = [i + m for m in splits]

    # The path again: each waypoint at its altitude; the points added on a leg go in front of
    # the waypoint that ends it (or of the return to launch: the way home keeps its clearance
    # too). A plane's approach and landing keep the altitudes of its landing sequence.
    leg_end = {point: k for k, point in enumerate(track)}  # point index -> its place in the track
    points: list[PathPoint] = []
    wp_s: list[float] = [0.0]
    wp_alt: list[float] = [float(profile[0])]
    lands_itself = any(p.role is Role.APPROACH for p in flat.points)  # a plane; else RTL
    for index, point in enumerate(flat.points):
        place = leg_end.get(index, 0)  # > 0: it ends leg place - 1 of the track
        rtl = point.role is Role.LANDING and not lands_itself
        if place > 0 and (point.is_waypoint or rtl):
            for m in extra_by_leg.get(place - 1, []):
                points.append(
                    PathPoint(
                        xy=(float(x[m]), float(y[m])), role=Role.TERRAIN, pass_index=point.pass_index,
                        line_index=point.line_index, alt_m=float(profile[m] - home_ground),
                    )
                )  # fmt: skip
                wp_s.append(float(s[m]))
                wp_alt.append(float(profile[m]))
        if place > 0 and point.is_waypoint:
            sample = point_sample[place]
            points.append(dataclasses.replace(point, alt_m=float(profile[sample] - home_ground)))
            wp_s.append(float(path_s[place]))
            wp_alt.append(float(profile[sample]))
        else:
            points.append(point)
    wp_s.append(float(s[-1]))
    wp_alt.append(float(profile[-1]))
    new_path = dataclasses.replace(flat, points=tuple(points))

    # What the vehicle flies: straight legs between waypoints.
    flown = np.interp(s, np.asarray(wp_s), np.asarray(wp_alt))
    agl_path = flown - ground
    # The take-off climb and the final descent are at home, not along the legs.
    body = slice(int(point_sample[1]) if len(point_sample) > 2 else 0, int(point_sample[-2]) + 1)
    clearance = float(np.min(agl_path[body])) if agl_path[body].size else alt_agl_m
    if clearance < MIN_CLEARANCE_M:
        m = int(np.argmin(np.where(np.arange(len(s)) >= body.start, agl_path, np.inf)))
        lon, lat = frame.to_lonlat(x[m], y[m])
        raise PlanningError(
            f"the path passes {clearance:.1f} m above the ground at lon {float(lon):.6f}, lat "
            f"{float(lat):.6f} (the DEM rises {float(ground[m] - home_ground):.0f} m above home); "
            f"set follow = true in [terrain], or fly higher"
        )
    agl_max = float(np.max(agl_path[body])) if agl_path[body].size else alt_agl_m
    if agl_max > max_alt_agl_m + 1e-6:
        m = int(np.argmax(np.where(np.arange(len(s)) >= body.start, agl_path, -np.inf)))
        lon, lat = frame.to_lonlat(x[m], y[m])
        raise PlanningError(
            f"the path is {agl_max:.1f} m above the ground at lon {float(lon):.6f}, lat {float(lat):.6f}, "
            f"above max_alt_agl_m = {max_alt_agl_m:g} (the ground falls away faster than the vehicle "
            f"may descend); raise max_descent_rate_m_s or lower speed_m_s"
            if terrain.follow
            else f"the ground falls {float(home_ground - ground[m]):.0f} m below home at lon "
            f"{float(lon):.6f}, lat {float(lat):.6f}, so the flight is {agl_max:.1f} m above it, "
            f"above max_alt_agl_m = {max_alt_agl_m:g}; set follow = true in [terrain]"
        )

    # Stations: altitude from the flown legs, height above the ground below them.
    st = built.stations
    n = len(st)
    st_alt = np.interp(flat.station_distance_m(along), np.asarray(wp_s), np.asarray(wp_alt))
    st_ground = dem.elevation_at(st.x_m, st.y_m, frame) if n else np.zeros(0)
    st_agl = st_alt - st_ground
    # Footprints cast on the DEM from each station's flown position (rays through a grid of the
    # image), the GSD scaled by the height above the ground below the camera.
    scale = st_agl / alt_agl_m
    corners = st.footprint_xy_m
    cast = np.zeros((0, _GRID * _GRID, 3))
    if n:
        up = _up_bearing_grid_deg(st.footprint_xy_m)
        cast = cast_on_dem(
            camera, st.x_m, st.y_m, st_alt, up, st.tilt_deg, dem, frame, image_grid_mm(camera, _GRID)
        )
        corners = cast[:, [0, _GRID - 1, _GRID * _GRID - 1, _GRID * (_GRID - 1)], :2]
        clon, clat = frame.to_lonlat(corners[..., 0].ravel(), corners[..., 1].ravel())
        corners_ll = np.stack([clon.reshape(n, 4), clat.reshape(n, 4)], axis=-1)
    else:
        corners_ll = st.footprint_lonlat_deg
    stations = dataclasses.replace(
        st,
        alt_rel_home_m=st_alt - home_ground,
        alt_agl_m=st_agl,
        gsd_cm=st.gsd_cm * scale,
        footprint_xy_m=corners,
        footprint_lonlat_deg=corners_ll,
    )
    overlaps = cast_overlaps(stations, cast, passes)
    front_min = min((o.front_pct for o in overlaps), default=100.0)
    side_min = min((o.side_pct for o in overlaps), default=100.0)

    def lonlat_of(xy: tuple[float, float] | None) -> tuple[float | None, float | None]:
        if xy is None:
            return None, None
        lon, lat = frame.to_lonlat(xy[0], xy[1])
        return round(float(lon), 7), round(float(lat), 7)

    front_at = next((o.front_xy for o in overlaps if o.front_pct == front_min), None)
    side_at = next((o.side_xy for o in overlaps if o.side_pct == side_min), None)
    nadir = st.tilt_deg == 0.0
    if n and nadir.any():
        # Height above the highest ground the frame sees, over the planned height: the frame's
        # size there, relative to flat ground.
        highest = cast[nadir, :, 2].max(axis=1)
        scale_min = float(np.min((st_alt[nadir] - highest) / alt_agl_m))
    else:
        scale_min = 1.0
    new_home = dataclasses.replace(home, alt_amsl_m=home_ground)
    mission = built.emitter(new_path, new_home)
    summary = TerrainSummary(
        dem=dem.path.name,
        follow=terrain.follow,
        home_ground_amsl_m=home_ground,
        ground_min_amsl_m=float(ground.min()),
        ground_max_amsl_m=float(ground.max()),
        station_alt_agl_min_m=float(st_agl.min()) if n else alt_agl_m,
        station_alt_agl_max_m=float(st_agl.max()) if n else alt_agl_m,
        gsd_min_cm=float(stations.gsd_cm.min()) if n else 0.0,
        gsd_max_cm=float(stations.gsd_cm.max()) if n else 0.0,
        front_overlap_min_pct=front_min,
        side_overlap_min_pct=side_min,
        front_overlap_min_lon_deg=lonlat_of(front_at)[0],
        front_overlap_min_lat_deg=lonlat_of(front_at)[1],
        side_overlap_min_lon_deg=lonlat_of(side_at)[0],
        side_overlap_min_lat_deg=lonlat_of(side_at)[1],
        path_alt_agl_min_m=clearance,
        path_alt_agl_max_m=agl_max,
        alt_rel_home_max_m=float(np.max(flown) - home_ground),
        waypoints_added=sum(len(v) for v in extra_by_leg.values()),
        footprint_scale=footprint_scale,
        footprint_scale_min=scale_min,
    )
    log.info("terrain: %d waypoints added, height above ground %.1f-%.1f m", summary.waypoints_added,
             summary.station_alt_agl_min_m, summary.station_alt_agl_max_m)  # fmt: skip
    built_t = dataclasses.replace(
        built, path=new_path, mission=mission, stations=stations, cast_overlaps=tuple(overlaps)
    )
    return built_t, new_home, summary


#: Rays per image side cast on the DEM for each frame (a _GRID x _GRID grid, border included).
_GRID = 9


def _up_bearing_grid_deg(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """The grid bearing the top of each image points toward, from its flat-ground footprint
    (TL, TR, BR, BL): from the bottom edge's middle to the top edge's."""
    top = (corners[:, 0] + corners[:, 1]) / 2.0
    bottom = (corners[:, 3] + corners[:, 2]) / 2.0
    d = top - bottom
    return np.asarray(np.degrees(np.arctan2(d[:, 0], d[:, 1])) % 360.0, float)


#: Cuts across each pair of neighbouring footprints at which their overlap is measured.
_SLICES = 17


def footprint_border(cast: NDArray[np.float64], grid: int) -> NDArray[np.float64]:
    """The border of each cast image grid (N, grid*grid, >=2) as a ring (N, 4 (grid - 1), 2):
    top row, right column, bottom row back, left column up."""
    idx = np.arange(grid * grid).reshape(grid, grid)
    ring = np.concatenate([idx[0, :-1], idx[:-1, -1], idx[-1, :0:-1], idx[:0:-1, 0]])
    return np.asarray(cast[:, ring, :2], float)


def slice_overlap_shares(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    s_lo: NDArray[np.float64],
    s_hi: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """For pairs of footprint rings ``a``, ``b`` (M, K, 2) in coordinates (s, t), where b lies
    beyond a in t: cut both at _SLICES values of s across the part of ``s_lo``..``s_hi`` (the
    stretch the pair answers for) they both span, and at each cut take the length both cover
    over the longer of the two cuts (negative: the gap between them, over the longer cut).
    Returns each pair's smallest share and the s where it is (NaN: no common stretch)."""
    m = a.shape[0]
    if m == 0:
        return np.zeros(0), np.zeros(0)
    lo = np.maximum(np.maximum(a[..., 0].min(axis=1), b[..., 0].min(axis=1)), s_lo)
    hi = np.minimum(np.minimum(a[..., 0].max(axis=1), b[..., 0].max(axis=1)), s_hi)
    frac = (np.arange(_SLICES) + 0.5) / _SLICES
    s = lo[:, None] + frac[None, :] * (hi - lo)[:, None]  # (M, S)
    t_lo = np.minimum(a[..., 1].min(axis=1), b[..., 1].min(axis=1)) - 1.0
    t_hi = np.maximum(a[..., 1].max(axis=1), b[..., 1].max(axis=1)) + 1.0
    ends = np.stack(
        [
            np.stack([s, np.broadcast_to(t_lo[:, None], s.shape)], axis=-1),
            np.stack([s, np.broadcast_to(t_hi[:, None], s.shape)], axis=-1),
        ],
        axis=2,
    ).reshape(m * _SLICES, 2, 2)
    cuts = shapely.linestrings(ends)
    poly_a = np.repeat(shapely.polygons(a), _SLICES)
    poly_b = np.repeat(shapely.polygons(b), _SLICES)
    ba = shapely.bounds(shapely.intersection(poly_a, cuts)).reshape(m, _SLICES, 4)
    bb = shapely.bounds(shapely.intersection(poly_b, cuts)).reshape(m, _SLICES, 4)
    a_lo, a_hi, b_lo, b_hi = ba[..., 1], ba[..., 3], bb[..., 1], bb[..., 3]
    both = np.minimum(a_hi, b_hi) - np.maximum(a_lo, b_lo)
    longer = np.maximum(a_hi - a_lo, b_hi - b_lo)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = both / longer
    share = np.where(np.isfinite(share) & (hi > lo)[:, None], share, np.inf)
    k = np.argmin(share, axis=1)
    best = share[np.arange(m), k]
    where = s[np.arange(m), k]
    best = np.where(np.isfinite(best), best, np.nan)
    return best, np.where(np.isfinite(best), where, np.nan)


def cast_overlaps(stations: Stations, cast: NDArray[np.float64], passes: list[PassPlan]) -> list[CastOverlap]:
    """The smallest forward and side overlap of each nadir pass's neighbouring frames, judged
    from their footprints cast on the DEM (``cast``: (N, _GRID * _GRID, 3) ground points of the
    image grid, see cast_on_dem) themselves.

    In the pass's frame (u along the lines, v across): forward, each pair of consecutive frames
    of a run; side, each frame and the frame of the next line nearest it along the line. Each
    pair's two footprints are cut across the direction that separates them (at fixed v for
    forward pairs, fixed u for side pairs) at _SLICES places along the stretch the pair answers
    for (forward: the band of the line, a line spacing wide; side: the first frame's trigger
    step), and
    at each cut the length both cover is taken over the longer cut: over flat ground, Eq. 3-5's
    1 - B / D; over relief, the overlap where the footprints come closest to parting. Negative:
    a gap."""
    out: list[CastOverlap] = []
    nadir = stations.tilt_deg == 0.0
    if not nadir.any() or cast.shape[0] == 0:
        return out
    ring_xy = footprint_border(cast, _GRID)
    for pp in passes:
        if pp.tilt_deg != 0.0:
            continue
        sel = np.flatnonzero(nadir & (stations.pass_index == pp.index))
        if sel.size == 0:
            continue
        t = math.radians(pp.direction_deg)
        sin_t, cos_t = math.sin(t), math.cos(t)
        u_st = stations.x_m[sel] * sin_t + stations.y_m[sel] * cos_t
        v_st = stations.x_m[sel] * cos_t - stations.y_m[sel] * sin_t
        ring = ring_xy[sel]
        ring_u = ring[..., 0] * sin_t + ring[..., 1] * cos_t
        ring_v = ring[..., 0] * cos_t - ring[..., 1] * sin_t
        line = stations.line_index[sel]
        front_pairs: list[tuple[int, int]] = []
        for row in np.unique(line):
            k = np.flatnonzero(line == row)
            k = k[np.argsort(u_st[k], kind="stable")]
            for a, b in itertools.pairwise(k):
                if u_st[b] - u_st[a] <= pp.trigger_distance_m * 1.01:  # else a break in the line
                    front_pairs.append((int(a), int(b)))
        side_pairs: list[tuple[int, int]] = []
        order = sorted(np.unique(line), key=lambda r: float(np.mean(v_st[line == r])))
        for r0, r1 in itertools.pairwise(order):
            k0, k1 = np.flatnonzero(line == r0), np.flatnonzero(line == r1)
            if float(np.mean(v_st[k1]) - np.mean(v_st[k0])) > pp.line_spacing_m * 1.01:
                continue
            nearest = k1[np.argmin(np.abs(u_st[k0][:, None] - u_st[k1][None, :]), axis=1)]
            for a, b in zip(k0, nearest, strict=True):
                if abs(u_st[b] - u_st[a]) <= pp.trigger_distance_m:
                    side_pairs.append((int(a), int(b)))

        x_sel, y_sel = stations.x_m[sel], stations.y_m[sel]

        def judge(
            pairs: list[tuple[int, int]],
            cut: NDArray[np.float64],
            across: NDArray[np.float64],
            centre: NDArray[np.float64],
            half: float,
            x_sel: NDArray[np.float64] = x_sel,
            y_sel: NDArray[np.float64] = y_sel,
        ) -> tuple[float, tuple[float, float] | None]:
            if not pairs:
                return 100.0, None
            ia = np.array([p[0] for p in pairs])
            ib = np.array([p[1] for p in pairs])
            a = np.stack([cut[ia], across[ia]], axis=-1)
            b = np.stack([cut[ib], across[ib]], axis=-1)
            share, _ = slice_overlap_shares(a, b, centre[ia] - half, centre[ia] + half)
            if not np.isfinite(share).any():
                return 100.0, None
            j = int(np.nanargmin(share))
            mid_x = float(x_sel[ia[j]] + x_sel[ib[j]]) / 2.0
            mid_y = float(y_sel[ia[j]] + y_sel[ib[j]]) / 2.0
            return 100.0 * float(share[j]), (mid_x, mid_y)

        # Forward: cut at fixed v across the band the line answers for (a line spacing wide);
        # side: at fixed u along the stretch the first frame answers for (a trigger step long).
        front, front_xy = judge(front_pairs, ring_v, ring_u, v_st, pp.line_spacing_m / 2.0)
        side, side_xy = judge(side_pairs, ring_u, ring_v, u_st, pp.trigger_distance_m / 2.0)
        out.append(
            CastOverlap(
                pass_index=pp.index, front_pct=front, front_xy=front_xy, side_pct=side, side_xy=side_xy
            )
        )
    return out
