"""The layout of the plan's map, whoever draws it (planner.mapplot with matplotlib, planner.maprender
with Pillow): the page and the map's limits, the header and caption texts, the lines counted as
the legend counts them, the thinning of large layers, the round length of the scale bar and the
colours."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .kinds import PassKind
from .stats import median

if TYPE_CHECKING:  # not imported: map.png's helper process reads a MapPlan without the planner
    from .mapview import MapPass, MapPlan
    from .plan import FlightPass, SurveyPlan

#: Stations drawn as dots at most (every k-th beyond).
DEFAULT_MAX_STATIONS = 10_000

PASS_COLOURS = {
    PassKind.NADIR: "#1565c0",
    PassKind.CROSSHATCH: "#7b1fa2",
    PassKind.OBLIQUE: "#ef6c00",
}
AREA_FACE = "#e3f1d4"
AREA_EDGE = "#2e7d32"
EXCLUSION_COLOUR = "#d32f2f"


def scale_bar_length_m(span_m: float) -> float:
    """The largest round length (1, 2 or 5 x 10^n m) at most a quarter of ``span_m``."""
    if not (span_m > 0 and math.isfinite(span_m)):
        return 1.0
    target = span_m / 4.0
    exponent = math.floor(math.log10(target))
    for mantissa in (5.0, 2.0, 1.0):
        length = mantissa * 10.0**exponent
        if length <= target * (1 + 1e-9):
            return length
    return 10.0**exponent  # pragma: no cover - 1 x 10^n <= target by construction


def thin_step(n: int, max_count: int) -> int:
    """Keep every ``thin_step``-th of ``n`` items so that at most ``max_count`` remain (>= 1)."""
    return 1 if n <= max_count or max_count <= 0 else -(-n // max_count)


def ordinal(k: int) -> str:
    """1st, 2nd, 3rd, 4th, ..., 11th, 12th, 13th, ..., 21st."""
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def thin(n: int, max_count: int) -> tuple[NDArray[np.int64], int]:
    """Every k-th index of ``range(n)``, at most ``max_count`` of them, and k."""
    if max_count <= 0:
        return np.zeros(0, dtype=np.int64), 0
    step = thin_step(n, max_count)
    return np.arange(0, n, step, dtype=np.int64), step


def pass_line_count(flight_pass: FlightPass | MapPass, tolerance_m: float = 0.01) -> int:
    """How many lines (rows) a pass flies: its camera-on segments grouped by their offset across
    the pass direction (a line that crosses a hole or a concave bay is flown as two or more
    segments of one row). The map's header and legend both count with this."""
    lines = flight_pass.lines
    if not lines:
        return 0
    dx = dy = 0.0
    for line in lines:  # the direction of the first segment of positive length
        dx, dy = line.end_xy_m[0] - line.start_xy_m[0], line.end_xy_m[1] - line.start_xy_m[1]
        if math.hypot(dx, dy) > 0:
            break
    norm = math.hypot(dx, dy)
    if norm == 0:  # every segment a single point: one row per distinct point
        return len(
            {(round(ln.start_xy_m[0] / tolerance_m), round(ln.start_xy_m[1] / tolerance_m)) for ln in lines}
        )
    ux, uy = dx / norm, dy / norm
    for line in lines:
        ex, ey = line.end_xy_m[0] - line.start_xy_m[0], line.end_xy_m[1] - line.start_xy_m[1]
        length = math.hypot(ex, ey)
        if length > 0 and abs(ux * ey - uy * ex) / length > 1e-6:
            # Segments of several bearings (a corridor's lines follow its bends): rows are not
            # offsets across one direction; count the lines the planner numbered.
            return len({ln.line_index for ln in lines})
    offsets = sorted(-ux * ln.start_xy_m[1] + uy * ln.start_xy_m[0] for ln in lines)
    rows = 1
    for before, after in itertools.pairwise(offsets):
        if after - before > tolerance_m:
            rows += 1
    return rows


def lines_text(rows: int, segments: int) -> str:
    """ "12 lines", or "12 lines in 15 segments" where holes cut lines."""
    text = f"{rows:,} line{'s' if rows != 1 else ''}"
    if segments != rows:
        text += f" in {segments:,} segments"
    return text


def shown_text(count: int, total: int, step: int, what: str) -> str:
    """What the legend says of a thinned layer: all, none, or every k-th of the total."""
    if count == total:
        return f"{what} (all {total:,})"
    if step == 0:
        return f"{what}: none of {total:,} shown"
    return f"{what}: every {ordinal(step)} of\n{total:,} shown ({count:,})"


@dataclass(frozen=True)
class MapFrame:
    """Where the map sits on the page: its limits in metres from home (x0, x1, y0, y1, at
    equal scale), the larger data span, and the page layout in inches (map box, margins)."""

    limits: tuple[float, float, float, float]
    span_m: float
    map_w_in: float
    map_h_in: float
    left_in: float
    right_in: float
    top_in: float
    bottom_in: float

    @property
    def fig_w_in(self) -> float:
        return self.left_in + self.map_w_in + self.right_in

    @property
    def fig_h_in(self) -> float:
        return self.bottom_in + self.map_h_in + self.top_in

    @property
    def points_per_m(self) -> float:
        return self.map_w_in * 72.0 / (self.limits[1] - self.limits[0])


def map_frame(plan: SurveyPlan | MapPlan) -> MapFrame:
    """The extent of everything drawn (area, exclusions, path, footprints, home), padded, and a
    page shaped like it (within limits): margins for the title lines, the axis labels and
    caption, and the legend on the right."""
    ox, oy = plan.home_xy_m
    st = plan.stations
    boxes = [plan.area_xy.bounds] if not plan.area_xy.is_empty else []
    boxes += [z.bounds for z in plan.exclusions_xy if not z.is_empty]
    xs = [b[0] for b in boxes] + [b[2] for b in boxes] + [ox]
    ys = [b[1] for b in boxes] + [b[3] for b in boxes] + [oy]
    if len(plan.path_xy_m):
        xs += [float(np.min(plan.path_xy_m[:, 0])), float(np.max(plan.path_xy_m[:, 0]))]
        ys += [float(np.min(plan.path_xy_m[:, 1])), float(np.max(plan.path_xy_m[:, 1]))]
    if len(st):
        fp = st.footprint_xy_m
        xs += [float(np.min(fp[..., 0])), float(np.max(fp[..., 0]))]
        ys += [float(np.min(fp[..., 1])), float(np.max(fp[..., 1]))]
    x0, x1 = min(xs) - ox, max(xs) - ox
    y0, y1 = min(ys) - oy, max(ys) - oy
    span = max(x1 - x0, y1 - y0, 10.0)
    pad = 0.06 * span
    x0, x1, y0, y1 = x0 - pad, x1 + pad, y0 - pad, y1 + pad
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    map_w_in = 9.0
    map_h_in = float(np.clip(map_w_in * aspect, 4.5, 12.0))
    # widen the short side so that the data fill the map box at equal scale
    box_ratio = map_h_in / map_w_in
    if (y1 - y0) / (x1 - x0) > box_ratio:
        grow = ((y1 - y0) / box_ratio - (x1 - x0)) / 2
        x0, x1 = x0 - grow, x1 + grow
    else:
        grow = ((x1 - x0) * box_ratio - (y1 - y0)) / 2
        y0, y1 = y0 - grow, y1 + grow
    return MapFrame(
        limits=(x0, x1, y0, y1),
        span_m=span,
        map_w_in=map_w_in,
        map_h_in=map_h_in,
        left_in=0.85,
        right_in=3.4,
        top_in=1.0,
        bottom_in=1.0,
    )


def header_text(plan: SurveyPlan) -> str:
    """The line under the title: GSD, height, lines (counted as the legend counts them)..."""
    s = plan.summary
    rows = sum(pass_line_count(p) for p in plan.passes)
    segments = sum(len(p.lines) for p in plan.passes)
    return (
        f"GSD {s.gsd_cm:.2f} cm  |  {s.altitude_agl_m:.1f} m above ground  |  "
        f"{lines_text(rows, segments)}, "
        f"{s.pass_count} pass{'es' if s.pass_count != 1 else ''}  |  "
        f"{s.photo_count:,} photos  |  {s.area_m2 / 10_000:,.2f} ha  |  "
        f"{s.flight_distance_m / 1000:,.1f} km, {s.flight_time_s / 60:,.0f} min"
    )


def caption_text(plan: SurveyPlan) -> str:
    """The grid and the angle between grid north and true north at home."""
    convergence_deg = plan.frame.true_north_grid_bearing_deg(plan.home.lon_deg, plan.home.lat_deg)
    epsg = plan.frame.epsg
    crs_name = f"EPSG:{epsg} ({plan.frame.crs.name})" if epsg else plan.frame.crs.name
    return (
        f"Grid: {crs_name}, metres from home. The north arrow points to grid north; "
        f"true north is {abs(convergence_deg):.2f} deg "
        f"{'east' if convergence_deg >= 0 else 'west'} of it at home."
    )


def pass_legend_counts(plan: SurveyPlan) -> dict[PassKind, tuple[int, int]]:
    """Per kind of pass: (lines, camera-on segments), in the order the passes come."""
    counts: dict[PassKind, tuple[int, int]] = {}
    for p in plan.passes:
        if not p.lines:
            continue
        rows, segments = counts.get(p.kind, (0, 0))
        counts[p.kind] = (rows + pass_line_count(p), segments + len(p.lines))
    return counts


#: Colours told apart on the map: a nadir pass at another height (multi-scale) and each oblique
#: look direction get their own, in the family of their kind.
NADIR_HEIGHT_COLOURS = ("#1565c0", "#00897b", "#283593", "#0097a7")
OBLIQUE_LOOK_COLOURS = ("#ef6c00", "#c62828", "#f9a825", "#6d4c41", "#ad1457", "#ff8a65")
#: Dots or outlines closer than this on the page (points) merge into a mat: not drawn.
MIN_VISIBLE_SPACING_PT = 3.0
#: Station dots per square inch of the area on the page beyond which they are not drawn: passes
#: crossing each other (crosshatch, obliques) turn more into a mat even when each line's are apart.
MAX_STATIONS_PER_IN2 = 80.0
#: Footprint outlines drawn at most before they are left out (a mat whatever the thinning).
MAX_VISIBLE_FOOTPRINTS = 1500


@dataclass(frozen=True)
class PassStyle:
    """How one group of passes is drawn: its colour and its legend label (lines counted as the
    header counts them)."""

    colour: str
    label: str
    pass_indices: tuple[int, ...]


def pass_styles(plan: SurveyPlan | MapPlan) -> list[PassStyle]:
    """One style per kind of pass, height and look direction, in the order the passes come:
    nadir passes at different heights (a multi-scale block) and oblique passes looking different
    ways are told apart by colour; one height and one look per kind keep the kind's colour."""
    groups: dict[tuple[PassKind, float, float | None], list[FlightPass | MapPass]] = {}
    for p in plan.passes:
        if p.lines:
            look = None if p.look_heading_deg is None else round(p.look_heading_deg % 360.0, 1)
            groups.setdefault((p.kind, round(p.alt_agl_m, 1), look), []).append(p)
    heights = sorted({alt for (kind, alt, _) in groups if kind is not PassKind.OBLIQUE}, reverse=False)
    looks = sorted({look for (kind, _, look) in groups if kind is PassKind.OBLIQUE and look is not None})
    several_heights = len({alt for (_, alt, _) in groups}) > 1
    styles = []
    for (kind, alt, look), passes in groups.items():
        rows = sum(pass_line_count(p) for p in passes)
        segments = sum(len(p.lines) for p in passes)
        where = f" at {alt:g} m" if several_heights else ""
        if kind is PassKind.OBLIQUE and look is not None:
            colour = OBLIQUE_LOOK_COLOURS[looks.index(look) % len(OBLIQUE_LOOK_COLOURS)]
            what = f"oblique {passes[0].tilt_deg:g} deg\nlooking {look:g} deg{where}"
        elif kind is PassKind.NADIR:
            colour = NADIR_HEIGHT_COLOURS[heights.index(alt) % len(NADIR_HEIGHT_COLOURS)]
            what = f"nadir{where}"
        else:
            colour = PASS_COLOURS[kind]
            what = f"{kind.value}{where}"
        styles.append(
            PassStyle(
                colour, f"camera on, {what} ({lines_text(rows, segments)})", tuple(p.index for p in passes)
            )
        )
    return styles


def dots_visible(spacing_m: float, points_per_m: float) -> bool:
    """Whether marks ``spacing_m`` apart are told apart on a page of ``points_per_m``."""
    return spacing_m * points_per_m >= MIN_VISIBLE_SPACING_PT


@dataclass(frozen=True)
class Simplification:
    """What the map draws at its scale: footprints and stations only when they can be told
    apart, and the sentences the legend says of what it left out."""

    footprints: bool
    stations: bool
    notes: tuple[str, ...]


def simplification(plan: SurveyPlan | MapPlan, frame: MapFrame, footprint_step: int = 1) -> Simplification:
    """Footprints are drawn when there are at most MAX_VISIBLE_FOOTPRINTS and those drawn (every
    ``footprint_step``-th) are visibly apart along the lines; stations when consecutive ones are
    (every one: thinning would hide the crowding) and there are at most MAX_STATIONS_PER_IN2 per
    square inch of the area on the page (crossing passes)."""
    st = plan.stations
    n = len(st)
    if n == 0:
        return Simplification(True, True, ())
    ppm = frame.points_per_m
    triggers = [p.trigger_distance_m for p in plan.passes if p.lines]
    trigger_m = median(triggers) if triggers else 0.0
    footprints = n <= MAX_VISIBLE_FOOTPRINTS and dots_visible(trigger_m * max(footprint_step, 1), ppm)
    steps = np.hypot(np.diff(st.x_m), np.diff(st.y_m)) if n > 1 else np.zeros(0)
    spacing_m = median(steps[steps > 0]) if np.any(steps > 0) else math.inf
    area_in2 = max(plan.area_xy.area * (ppm / 72.0) ** 2, 1e-9)
    crowded = n > MAX_STATIONS_PER_IN2 * area_in2
    stations = dots_visible(spacing_m, ppm) and not crowded
    notes = []
    if not footprints:
        notes.append(f"frame footprints not drawn: {n:,} would\nhide the map (footprints.geojson)")
    if not stations:
        why = f"{n / area_in2:.0f} per square inch" if crowded else f"{spacing_m * ppm:.1f} pt apart"
        notes.append(f"exposure stations not drawn: {n:,},\n{why} at this scale (stations.geojson)")
    return Simplification(footprints, stations, tuple(notes))
