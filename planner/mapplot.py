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

import logging
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .errors import InputError
from .kinds import PassKind
from .maplayout import (
    AREA_EDGE,
    AREA_FACE,
    DEFAULT_MAX_STATIONS,
    EXCLUSION_COLOUR,
    PASS_COLOURS,
    caption_text,
    header_text,
    lines_text,
    map_frame,
    pass_legend_counts,
    scale_bar_length_m,
    shown_text,
    thin,
)
from .plan import SurveyPlan
from .stats import median

if TYPE_CHECKING:  # matplotlib is imported when a map is drawn (about 0.2 s), not with the module
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.path import Path as MplPath

log = logging.getLogger(__name__)


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
        ax.add_patch(PathPatch(area_path, facecolor=AREA_FACE, edgecolor=AREA_EDGE, lw=1.2, zorder=1))
    handles.append(Patch(facecolor=AREA_FACE, edgecolor=AREA_EDGE, label="area to cover"))
    if plan.exclusions_xy:
        for zone in plan.exclusions_xy:
            zone_path = polygon_path(zone, ox, oy)
            if zone_path is not None:
                ax.add_patch(
                    PathPatch(
                        zone_path,
                        facecolor=(0.83, 0.18, 0.18, 0.10),
                        edgecolor=EXCLUSION_COLOUR,
                        hatch="///",
                        lw=1.2,
                        zorder=2,
                    )
                )
        handles.append(
            Patch(
                facecolor=(0.83, 0.18, 0.18, 0.10),
                edgecolor=EXCLUSION_COLOUR,
                hatch="///",
                label=f"exclusion zones and holes ({len(plan.exclusions_xy)})",
            )
        )

    # footprints: thin translucent outlines, coloured by pass kind
    fp_index, fp_step = thin(n, max_footprints)
    if fp_index.size:
        fp_kinds = [kind_of_pass.get(int(p), PassKind.NADIR) for p in st.pass_index[fp_index]]
        fp_colours = [PASS_COLOURS[k] for k in fp_kinds]
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
                label=shown_text(int(fp_index.size), n, fp_step, "frame footprints"),
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
                colors=PASS_COLOURS[p.kind],
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
                color=PASS_COLOURS[kind],
                lw=1.6,
                label=f"camera on, {kind.value} ({lines_text(rows, count)})",
            )
        )

    st_index, st_step = thin(n, max_stations)
    if st_index.size:
        # dot size from the spacing of the dots drawn along their line, in points
        steps = np.hypot(np.diff(st.x_m[st_index]), np.diff(st.y_m[st_index]))
        spacing_pt = median(steps) * points_per_m if steps.size else 8.0
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
                label=shown_text(int(st_index.size), n, st_step, "exposure stations"),
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
    sorties: Sequence[SurveyPlan] = (),
) -> bytes:
    """The map of ``plan`` as PNG bytes (see :func:`render_map_png`)."""
    # Drawn with Pillow (planner/maprender.py): matplotlib's import alone costs more than a
    # small plan's planning and every other output together.
    from .maprender import png_bytes
    from .mapview import map_view

    return png_bytes(
        map_view(plan, sorties), max_footprints=max_footprints, max_stations=max_stations, dpi=dpi
    )


def render_map_png(
    plan: SurveyPlan,
    path: str | os.PathLike[str],
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
    dpi: int = 130,
    sorties: Sequence[SurveyPlan] = (),
) -> Path:
    """Render map.png of ``plan`` and write it atomically; returns the path written.

    ``max_footprints`` / ``max_stations``: frame footprints and station dots drawn at most,
    every k-th beyond (the legend says which and how many). ``dpi``: pixels
    per inch of the PNG (the figure is about 12 inches wide). ``sorties``: the plan's sorties (their
    own plans, numbered from 1), drawn as outlines with their numbers.
    """
    from .maprender import write_png
    from .mapview import map_view

    return write_png(
        map_view(plan, sorties), path, max_footprints=max_footprints, max_stations=max_stations, dpi=dpi
    )
