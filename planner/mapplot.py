"""map.png: a map of a :class:`~planner.plan.SurveyPlan` that a person reads at a glance.

Drawn in the plan's local projected frame (its UTM zone), in metres east and north of home,
with equal aspect: the area filled light green, exclusion zones hatched red, frame footprints
as thin translucent outlines, camera-on segments coloured by pass kind, the transit path
dashed, exposure stations as small dots, home, the entry of the first line with an arrow in
its direction, a scale bar of a round length and a north arrow. The north arrow points to
grid north of the UTM frame; the caption gives the angle to true north at home (meridian
convergence).

Large plans (hundreds of thousands of stations) are drawn with one collection per layer and
footprints and stations thinned to every k-th; the legend says which and how many.
matplotlib is used through its object API (``Figure`` with the Agg canvas), never pyplot, so
no global state is touched and threads can render side by side.
"""

from __future__ import annotations

import io
import itertools
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .errors import InputError
from .outputs import atomic_write_bytes
from .plan import FlightPass, PassKind, SurveyPlan

if TYPE_CHECKING:  # matplotlib is imported when a map is drawn (about 0.2 s), not with the module
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.path import Path as MplPath

log = logging.getLogger(__name__)

#: Stations drawn as dots at most (every k-th beyond).
DEFAULT_MAX_STATIONS = 10_000

_PASS_COLOURS = {
    PassKind.NADIR: "#1565c0",
    PassKind.CROSSHATCH: "#7b1fa2",
    PassKind.OBLIQUE: "#ef6c00",
}
_AREA_FACE = "#e3f1d4"
_AREA_EDGE = "#2e7d32"
_EXCLUSION = "#d32f2f"


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


def _thin_step(n: int, max_count: int) -> int:
    """Keep every ``thin_step``-th of ``n`` items so that at most ``max_count`` remain (>= 1)."""
    return 1 if n <= max_count or max_count <= 0 else -(-n // max_count)


def _ordinal(k: int) -> str:
    """1st, 2nd, 3rd, 4th, ..., 11th, 12th, 13th, ..., 21st."""
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def _thin(n: int, max_count: int) -> tuple[NDArray[np.int64], int]:
    """Every k-th index of ``range(n)``, at most ``max_count`` of them, and k."""
    if max_count <= 0:
        return np.zeros(0, dtype=np.int64), 0
    step = _thin_step(n, max_count)
    return np.arange(0, n, step, dtype=np.int64), step


def polygon_path(geom: Polygon | MultiPolygon, ox: float, oy: float) -> MplPath | None:
    """A compound matplotlib path (exteriors and holes) of a polygon, shifted by -origin."""
    from matplotlib.path import Path as MplPath

    parts = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    vertices: list[NDArray[np.float64]] = []
    codes: list[NDArray[np.uint8]] = []
    for part in parts:
        if part.is_empty:
            continue
        for ring in (part.exterior, *part.interiors):
            xy = np.asarray(ring.coords, dtype=np.float64) - (ox, oy)
            c = np.full(len(xy), MplPath.LINETO, dtype=np.uint8)
            c[0] = MplPath.MOVETO
            c[-1] = MplPath.CLOSEPOLY
            vertices.append(xy)
            codes.append(c)
    if not vertices:
        return None
    return MplPath(np.concatenate(vertices), np.concatenate(codes))


def pass_line_count(flight_pass: FlightPass, tolerance_m: float = 0.01) -> int:
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


def _lines_text(rows: int, segments: int) -> str:
    text = f"{rows:,} line{'s' if rows != 1 else ''}"
    if segments != rows:
        text += f" in {segments:,} segments"
    return text


def _shown(count: int, total: int, step: int, what: str) -> str:
    if count == total:
        return f"{what} (all {total:,})"
    if step == 0:
        return f"{what}: none of {total:,} shown"
    return f"{what}: every {_ordinal(step)} of\n{total:,} shown ({count:,})"


def draw_scale_bar(ax: Any, length_m: float, limits: tuple[float, float, float, float]) -> None:
    """A scale bar of ``length_m`` in the lower right corner of a matplotlib map whose ``limits``
    are (x0, x1, y0, y1) metres: alternating black and white quarters in a white box, the
    length written above (the plan's map and the check's report maps)."""
    from matplotlib.patches import Rectangle

    _, x1, y0, y1 = limits
    unit = (y1 - y0) / 100.0  # one hundredth of the map's height
    right = x1 - 6.0 * unit  # room for the label centred on the bar's end
    left = right - length_m
    bottom = y0 + 2.5 * unit
    ax.add_patch(
        Rectangle(
            (left - 2.0 * unit, bottom - 1.5 * unit),
            length_m + 7.0 * unit,
            6.0 * unit,
            facecolor="white",
            edgecolor="#424242",
            lw=0.8,
            alpha=0.9,
            zorder=9,
        )
    )
    for k in range(4):
        ax.add_patch(
            Rectangle(
                (left + k * length_m / 4, bottom),
                length_m / 4,
                1.2 * unit,
                facecolor="black" if k % 2 == 0 else "white",
                edgecolor="black",
                lw=0.8,
                zorder=10,
            )
        )
    label = f"{length_m / 1000:g} km" if length_m >= 1000 else f"{length_m:g} m"
    ax.text(left, bottom + 1.8 * unit, "0", ha="center", va="bottom", fontsize=8, zorder=10)
    ax.text(right, bottom + 1.8 * unit, label, ha="center", va="bottom", fontsize=9, zorder=10)


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


def map_frame(plan: SurveyPlan) -> MapFrame:
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
        f"{_lines_text(rows, segments)}, "
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


def render_map_figure(
    plan: SurveyPlan,
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
) -> Figure:
    """The map of ``plan`` as a ``Figure`` on an Agg canvas (see :func:`render_map_png`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, PathPatch

    if max_footprints < 0 or max_stations < 0:
        raise InputError(
            f"max_footprints = {max_footprints}, max_stations = {max_stations}: both must be 0 or more"
        )
    ox, oy = plan.home_xy_m
    st = plan.stations
    n = len(st)
    kind_of_pass = {p.index: p.kind for p in plan.passes}
    frame = map_frame(plan)
    x0, x1, y0, y1 = frame.limits
    span = frame.span_m
    map_w_in, map_h_in = frame.map_w_in, frame.map_h_in
    left_in, bottom_in = frame.left_in, frame.bottom_in
    fig_w_in, fig_h_in = frame.fig_w_in, frame.fig_h_in
    fig = Figure(figsize=(fig_w_in, fig_h_in), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((left_in / fig_w_in, bottom_in / fig_h_in, map_w_in / fig_w_in, map_h_in / fig_h_in))
    points_per_m = map_w_in * 72.0 / (x1 - x0)
    ax.set_facecolor("white")
    handles: list[Patch | Line2D] = []

    area_path = polygon_path(plan.area_xy, ox, oy)
    if area_path is not None:
        ax.add_patch(PathPatch(area_path, facecolor=_AREA_FACE, edgecolor=_AREA_EDGE, lw=1.2, zorder=1))
    handles.append(Patch(facecolor=_AREA_FACE, edgecolor=_AREA_EDGE, label="area to cover"))
    if plan.exclusions_xy:
        for zone in plan.exclusions_xy:
            zone_path = polygon_path(zone, ox, oy)
            if zone_path is not None:
                ax.add_patch(
                    PathPatch(
                        zone_path,
                        facecolor=(0.83, 0.18, 0.18, 0.10),
                        edgecolor=_EXCLUSION,
                        hatch="///",
                        lw=1.2,
                        zorder=2,
                    )
                )
        handles.append(
            Patch(
                facecolor=(0.83, 0.18, 0.18, 0.10),
                edgecolor=_EXCLUSION,
                hatch="///",
                label=f"exclusion zones and holes ({len(plan.exclusions_xy)})",
            )
        )

    # footprints: thin translucent outlines, coloured by pass kind
    fp_index, fp_step = _thin(n, max_footprints)
    if fp_index.size:
        fp_kinds = [kind_of_pass.get(int(p), PassKind.NADIR) for p in st.pass_index[fp_index]]
        fp_colours = [_PASS_COLOURS[k] for k in fp_kinds]
        ax.add_collection(
            PolyCollection(
                # an (N, 4, 2) array is a sequence of polygons; the stubs only say Sequence
                cast(Any, st.footprint_xy_m[fp_index] - (ox, oy)),
                closed=True,
                facecolors="none",
                edgecolors=fp_colours,
                linewidths=0.35,
                alpha=0.35,
                zorder=3,
            )
        )
        handles.append(
            Patch(
                facecolor="none",
                edgecolor="#607d8b",
                lw=0.6,
                label=_shown(int(fp_index.size), n, fp_step, "frame footprints"),
            )
        )

    # transit path (dashed), then the camera-on segments over it
    if len(plan.path_xy_m) >= 2:
        ax.plot(
            plan.path_xy_m[:, 0] - ox,
            plan.path_xy_m[:, 1] - oy,
            color="#424242",
            lw=0.8,
            ls=(0, (4, 3)),
            zorder=4,
        )
        handles.append(Line2D([], [], color="#424242", lw=0.8, ls=(0, (4, 3)), label="flight path"))
    layer = {PassKind.OBLIQUE: 5.0, PassKind.CROSSHATCH: 5.1, PassKind.NADIR: 5.2}
    for p in plan.passes:
        if not p.lines:
            continue
        # wide enough to see, narrow enough that neighbouring lines stay apart on the page
        line_w = float(np.clip(0.35 * p.line_spacing_m * points_per_m, 0.25, 1.6))
        segments = np.array([(ln.start_xy_m, ln.end_xy_m) for ln in p.lines], dtype=float)
        ax.add_collection(
            LineCollection(
                cast(Any, segments - (ox, oy)),
                colors=_PASS_COLOURS[p.kind],
                linewidths=line_w,
                capstyle="round",  # a one-photo segment (start = end) shows as a dot
                zorder=layer[p.kind],
            )
        )
    kinds_drawn = pass_legend_counts(plan)
    for kind, (rows, count) in kinds_drawn.items():
        handles.append(
            Line2D(
                [],
                [],
                color=_PASS_COLOURS[kind],
                lw=1.6,
                label=f"camera on, {kind.value} ({_lines_text(rows, count)})",
            )
        )

    st_index, st_step = _thin(n, max_stations)
    if st_index.size:
        # dot size from the spacing of the dots drawn along their line, in points
        steps = np.hypot(np.diff(st.x_m[st_index]), np.diff(st.y_m[st_index]))
        spacing_pt = float(np.median(steps)) * points_per_m if steps.size else 8.0
        ax.scatter(
            st.x_m[st_index] - ox,
            st.y_m[st_index] - oy,
            s=float(np.clip(0.5 * min(spacing_pt, 8.0) ** 2, 0.3, 8.0)),
            c="#212121",
            alpha=0.8 if st_index.size > 2000 else 1.0,
            linewidths=0,
            zorder=6,
        )
        handles.append(
            Line2D(
                [],
                [],
                ls="none",
                marker="o",
                ms=3,
                color="#212121",
                label=_shown(int(st_index.size), n, st_step, "exposure stations"),
            )
        )

    # home, entry and the direction of the first line
    ax.plot([0.0], [0.0], marker="^", ms=12, color="#ffd600", mec="black", mew=1.2, ls="none", zorder=8)
    handles.append(
        Line2D([], [], marker="^", ms=10, color="#ffd600", mec="black", ls="none", label="home (0, 0)")
    )
    if plan.passes and plan.passes[0].lines:
        first = plan.passes[0].lines[0]
        ex, ey = first.entry_xy_m[0] - ox, first.entry_xy_m[1] - oy
        # the arrow follows the line on the map (grid), whatever bearing convention it carries
        dx = first.end_xy_m[0] - first.start_xy_m[0]
        dy = first.end_xy_m[1] - first.start_xy_m[1]
        norm = math.hypot(dx, dy) or 1.0
        arrow_m = 0.08 * span
        ax.plot([ex], [ey], marker="o", ms=9, color="#00c853", mec="black", mew=1.0, ls="none", zorder=8)
        ax.annotate(
            "",
            xy=(ex + arrow_m * dx / norm, ey + arrow_m * dy / norm),
            xytext=(ex, ey),
            arrowprops={"arrowstyle": "-|>", "color": "#00c853", "lw": 2.2, "mutation_scale": 16},
            zorder=8,
        )
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                ms=8,
                color="#00c853",
                mec="black",
                ls="none",
                label=f"entry; first line heading {first.heading_deg:.0f} deg (true)",
            )
        )

    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("metres east of home (grid)")
    ax.set_ylabel("metres north of home (grid)")
    ax.grid(True, color="#eeeeee", lw=0.6, zorder=0)
    ax.set_axisbelow(True)
    ax.ticklabel_format(useOffset=False, style="plain")

    # scale bar and north arrow
    draw_scale_bar(ax, scale_bar_length_m(x1 - x0), (x0, x1, y0, y1))
    ax.annotate(
        "N",
        xy=(0.95, 0.96),
        xytext=(0.95, 0.84),
        xycoords="axes fraction",
        ha="center",
        va="top",
        fontsize=13,
        fontweight="bold",
        arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 2.0, "mutation_scale": 18},
        zorder=9,
    )

    fig.text(
        left_in / fig_w_in,
        1.0 - 0.2 / fig_h_in,
        plan.name,
        ha="left",
        va="top",
        fontsize=14,
        fontweight="bold",
    )
    fig.text(left_in / fig_w_in, 1.0 - 0.58 / fig_h_in, header_text(plan), ha="left", va="top", fontsize=10)
    fig.text(left_in / fig_w_in, 0.15 / fig_h_in, caption_text(plan), ha="left", fontsize=8, color="#424242")
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        frameon=False,
        borderaxespad=0.0,
    )
    return fig


def map_png_bytes(
    plan: SurveyPlan,
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
    dpi: int = 130,
) -> bytes:
    """The map of ``plan`` as PNG bytes (see :func:`render_map_png`)."""
    from PIL import Image

    from .maprender import draw_map

    if max_footprints < 0 or max_stations < 0:
        raise InputError(
            f"max_footprints = {max_footprints}, max_stations = {max_stations}: both must be 0 or more"
        )
    # Drawn with Pillow (planner/maprender.py): matplotlib's import alone costs more than a
    # small plan's planning and every other output together.
    rgb = draw_map(plan, max_footprints=max_footprints, max_stations=max_stations, dpi=dpi)
    # A map is a few flat colours and their anti-aliased edges: a 256-colour palette keeps
    # them (no dithering) and encodes 3-4x faster and 4x smaller than 24-bit colour.
    image = rgb.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG", compress_level=6)
    return buffer.getvalue()


def render_map_png(
    plan: SurveyPlan,
    path: str | os.PathLike[str],
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
    dpi: int = 130,
) -> Path:
    """Render map.png of ``plan`` and write it atomically; returns the path written.

    ``max_footprints`` / ``max_stations``: frame footprints and station dots drawn at most,
    every k-th beyond (the legend says which and how many). ``dpi``: pixels
    per inch of the PNG (the figure is about 12 inches wide).
    """
    data = map_png_bytes(plan, max_footprints=max_footprints, max_stations=max_stations, dpi=dpi)
    written = atomic_write_bytes(path, data)
    log.debug("wrote map: %s (%d bytes)", written, len(data))
    return written
