"""The check's four maps (PNG): views per cell, gaps, GSD and base-height ratio, in metres east
and north of the area's south-west corner in the check's frame, equal aspect, with a scale bar,
a north arrow (grid north of the frame) and a caption stating the origin (its latitude and
longitude) and the grid; the title above the map and its colour bar, wrapped; labels placed so
that they do not overlap (:func:`place_labels`). The GSD map's colour scale is anchored on the
target (the plan's GSD, else the block's median) and the check's tolerance (10 % coarser warns):
noise of a few hundredths of a centimetre stays one colour.

matplotlib is used through ``Figure`` and the Agg canvas, never pyplot (no global state).
"""

from __future__ import annotations

import io
import itertools
import logging
import textwrap
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch
from matplotlib.text import Text as MplText
from numpy.typing import NDArray

from planner.maplayout import scale_bar_length_m
from planner.mapplot import draw_scale_bar, polygon_path

from .check_result import CheckResult
from .check_stereo import STEREO_GOOD, STEREO_NONE, STEREO_WEAK, STEREO_WIDE

log = logging.getLogger(__name__)

#: View-count classes of the map: lower bounds and colours (red: unseen ... dark green: 9+).
VIEW_CLASSES = (0, 1, 2, 3, 5, 9)
VIEW_COLOURS = ("#d32f2f", "#fb8c00", "#fdd835", "#c5e1a5", "#66bb6a", "#1b5e20")
_GAP_COLOUR = "#d32f2f"
_FIGSIZE_IN = (7.0, 6.0)
_DPI = 110
#: The check warns when the median GSD is more than this fraction coarser than planned
#: (processing/check.py); the GSD map's colour scale spans the target -/+ this.
GSD_TOLERANCE = 0.10


# --- maps ----------------------------------------------------------------------------------------


class _Map:
    """One map figure in metres from the area's south-west corner."""

    def __init__(self, result: CheckResult, title: str) -> None:
        self.result = result
        minx, miny, maxx, maxy = result.area_xy.bounds
        fx = result.footprints_xy[..., 0]
        fy = result.footprints_xy[..., 1]
        # Show the area and every footprint, with a small margin.
        x0 = min(minx, float(np.min(fx)) if fx.size else minx)
        x1 = max(maxx, float(np.max(fx)) if fx.size else maxx)
        y0 = min(miny, float(np.min(fy)) if fy.size else miny)
        y1 = max(maxy, float(np.max(fy)) if fy.size else maxy)
        pad = 0.03 * max(x1 - x0, y1 - y0, 1.0)
        self.origin = (minx, miny)
        self.limits = (x0 - minx - pad, x1 - minx + pad, y0 - miny - pad, y1 - miny + pad)
        aspect = (self.limits[3] - self.limits[2]) / max(self.limits[1] - self.limits[0], 1e-9)
        height_in = min(max(1.9 + 4.6 * aspect, 3.8), 8.0)  # the map's proportions, little blank
        self.figure = Figure(figsize=(_FIGSIZE_IN[0], height_in), dpi=_DPI, layout="constrained")
        FigureCanvasAgg(self.figure)
        # Above the map and its colour bar (a figure title), wrapped: never under the colour bar.
        self.figure.suptitle(textwrap.fill(title, 62), fontsize=11, x=0.02, ha="left")
        self.ax = self.figure.add_subplot()
        self.ax.set_aspect("equal")
        self.ax.set_xlim(self.limits[0], self.limits[1])
        self.ax.set_ylim(self.limits[2], self.limits[3])
        self.ax.set_xlabel("metres east of the origin (grid)", fontsize=9)
        self.ax.set_ylabel("metres north of the origin (grid)", fontsize=9)
        # the caption as the figure's x label: the layout keeps room for it under the axes
        self.figure.supxlabel(
            textwrap.fill(self.caption(), 118), fontsize=6.5, color="#424242", x=0.01, ha="left"
        )
        self.ax.tick_params(labelsize=8)
        self.ax.set_facecolor("#f5f5f5")

    def caption(self) -> str:
        """The origin (the area's south-west corner: its latitude and longitude) and the grid."""
        frame = self.result.frame
        lon, lat = (float(v) for v in frame.to_lonlat(*self.origin))
        with warnings.catch_warnings():  # to_dict warns that a PROJ string may lose detail: not here
            warnings.simplefilter("ignore", UserWarning)
            params = frame.crs.to_dict()
        if frame.epsg:
            grid = f"grid EPSG:{frame.epsg} ({frame.crs.name}), metres. The arrow points to grid north"
        elif params.get("proj") == "tmerc":
            grid = (
                f"grid: transverse Mercator centred at {float(params.get('lat_0', 0.0)):.5f}, "
                f"{float(params.get('lon_0', 0.0)):.5f} (WGS84, scale 1), metres. The arrow points to grid "
                f"north, true north on the central meridian"
            )
        else:
            grid = f"grid {frame.crs.name}, metres. The arrow points to grid north"
        return (
            f"Origin (0, 0): the area's south-west corner, {abs(lat):.5f} deg {'N' if lat >= 0 else 'S'}, "
            f"{abs(lon):.5f} deg {'E' if lon >= 0 else 'W'}; {grid}. The check's files (coverage.tif, "
            f"report.json) are in {self.result.output_crs()[0]}."
        )

    def north_arrow(self) -> None:
        """An arrow to grid north in the map's upper right corner, labelled N."""
        _, x1, y0, y1 = self.limits
        unit = (y1 - y0) / 100.0
        x = x1 - 4.5 * unit
        self.ax.annotate(
            "N",
            xy=(x, y1 - 2.5 * unit),
            xytext=(x, y1 - 13.0 * unit),
            ha="center",
            va="top",
            fontsize=10,
            weight="bold",
            arrowprops={"arrowstyle": "-|>", "lw": 1.8, "color": "black"},
            zorder=11,
            gid="north-arrow",
        )

    @property
    def raster_extent(self) -> tuple[float, float, float, float]:
        west, south, east, north = self.result.extent_xy_m
        ox, oy = self.origin
        return (west - ox, east - ox, south - oy, north - oy)

    def area_outline(self, colour: str = "black", width: float = 1.4) -> None:
        path = polygon_path(self.result.area_xy, *self.origin)
        if path is not None:
            self.ax.add_patch(PathPatch(path, facecolor="none", edgecolor=colour, lw=width, zorder=6))

    def footprints(self, max_count: int = 600, colour: str = "#616161") -> None:
        rings = self.result.footprints_xy
        step = max(1, -(-rings.shape[0] // max_count)) if rings.shape[0] else 1
        shifted = rings[::step] - np.asarray(self.origin)
        self.ax.add_collection(
            PolyCollection(list(shifted), facecolor="none", edgecolor=colour, lw=0.4, alpha=0.6, zorder=4)
        )

    def centres(self, colour: str = "black") -> None:
        c = self.result.centres_xy
        if c.size:
            self.ax.plot(
                c[:, 0] - self.origin[0],
                c[:, 1] - self.origin[1],
                ".",
                ms=2.5,
                color=colour,
                zorder=7,
            )

    def scale_bar(self) -> None:
        """The plan map's scale bar (planner.mapplot), so both read alike."""
        draw_scale_bar(self.ax, scale_bar_length_m(self.limits[1] - self.limits[0]), self.limits)

    def finish(self) -> Figure:
        """The scale bar and the north arrow drawn; the figure."""
        self.scale_bar()
        self.north_arrow()
        return self.figure

    def png(self) -> bytes:
        self.finish()
        buffer = io.BytesIO()
        self.figure.savefig(buffer, format="png", dpi=_DPI)
        return buffer.getvalue()


def _draw_raster(m: _Map, raster: NDArray[Any], blank: NDArray[np.bool_], **style: Any) -> Any:
    """A raster over the map: opaque inside the area, pale outside it (context: the turns and
    the outer halves of edge frames are not judged); ``blank`` cells are not drawn."""
    values = np.asarray(raster, dtype=np.float64)
    blank = blank | ~np.isfinite(values)
    inside = m.result.in_area
    common = {"extent": m.raster_extent, "origin": "upper", "interpolation": "nearest", **style}
    m.ax.imshow(np.ma.masked_array(values, mask=blank | inside), alpha=0.3, zorder=1, **common)
    return m.ax.imshow(np.ma.masked_array(values, mask=blank | ~inside), zorder=2, **common)


def view_count_png(result: CheckResult) -> bytes:
    """Views per cell: red unseen, orange 1, yellow 2, greens 3-4, 5-8, 9+; paler outside the
    area."""
    m = _Map(result, "Views per ground cell")
    bounds = [*VIEW_CLASSES, max(VIEW_CLASSES[-1] + 1, int(result.view_count.max(initial=0)) + 1)]
    cmap = ListedColormap(list(VIEW_COLOURS))
    norm = BoundaryNorm(bounds, cmap.N)
    # Unseen cells outside the area are not drawn: only inside the area is a gap red.
    outside_unseen = ~result.in_area & (result.view_count == 0)
    image = _draw_raster(m, result.view_count, outside_unseen, cmap=cmap, norm=norm)
    m.area_outline()
    m.centres()
    bar = m.figure.colorbar(
        image, ax=m.ax, shrink=0.8, ticks=[(a + b) / 2 for a, b in itertools.pairwise(bounds)]
    )
    bar.ax.set_yticklabels(["0 (gap)", "1", "2", "3-4", "5-8", "9+"])
    bar.set_label("frames that see the cell", fontsize=9)
    return m.png()


def gaps_png(result: CheckResult) -> bytes:
    """The area, every footprint's outline and the gaps in red, numbered as in the table."""
    title = f"Gaps: {len(result.gaps)}" + (f", {result.gap_area_m2:,.0f} m2" if result.gaps else " (none)")
    m = _Map(result, title)
    path = polygon_path(result.area_xy, *m.origin)
    if path is not None:
        m.ax.add_patch(PathPatch(path, facecolor="#e8f5e9", edgecolor="none", zorder=1))
    m.footprints()
    for gap in result.gaps:
        gp = polygon_path(gap.polygon_xy, *m.origin)
        if gp is not None:
            m.ax.add_patch(
                PathPatch(gp, facecolor=_GAP_COLOUR, edgecolor="#7f0000", lw=0.8, alpha=0.85, zorder=5)
            )
    m.area_outline()
    m.centres()
    anchors = []
    for gap in result.gaps:
        c = gap.polygon_xy.representative_point()
        anchors.append((c.x - m.origin[0], c.y - m.origin[1]))
    place_labels(m.ax, anchors, [str(gap.index) for gap in result.gaps])
    return m.png()


#: Offsets tried for a label that would overlap another, points, in rings around its anchor.
_LABEL_DIRECTIONS = ((0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (-1, 1), (1, -1), (-1, -1))


def _text_box(label: Any, renderer: Any) -> Any:
    """The window extent of an annotation's text and its frame, without the leader line."""
    label.update_positions(renderer)  # the text's place in display coordinates, as drawn
    return MplText.get_window_extent(label, renderer).expanded(1.3, 1.3)


def place_labels(ax: Any, anchors: Sequence[tuple[float, float]], texts: Sequence[str]) -> list[Any]:
    """Label each anchor (data coordinates) so that no two labels overlap: a label that would
    overlap one already placed moves out in rings of 14 pt around its anchor, with a leader line,
    to a place inside the map.
    Labels are placed in the order given (the largest gap first keeps its place). Returns the
    annotations."""
    figure = ax.figure
    renderer = figure.canvas.get_renderer()
    figure.canvas.draw()
    placed: list[Any] = []
    boxes: list[Any] = []
    style = {
        "fontsize": 9,
        "fontweight": "bold",
        "color": "black",
        "ha": "center",
        "va": "center",
        "zorder": 8,
        "bbox": {"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": _GAP_COLOUR, "lw": 0.8},
    }
    inside = ax.get_window_extent(renderer)

    def clashes(box: Any) -> bool:
        # Another label in the way, or a place (partly) outside the map.
        return any(box.overlaps(other) for other in boxes) or not (
            inside.x0 <= box.x0 and box.x1 <= inside.x1 and inside.y0 <= box.y0 and box.y1 <= inside.y1
        )

    for (x, y), text in zip(anchors, texts, strict=True):
        label = ax.annotate(text, (x, y), xytext=(0, 0), textcoords="offset points", **style)
        box = _text_box(label, renderer)
        ring = 0
        while clashes(box) and ring < 12:
            ring += 1
            for dx, dy in _LABEL_DIRECTIONS:
                label.set_position((14 * ring * dx, 14 * ring * dy))
                box = _text_box(label, renderer)
                if not clashes(box):
                    break
        if ring:
            label.remove()
            offset = label.get_position()
            label = ax.annotate(
                text,
                (x, y),
                xytext=offset,
                textcoords="offset points",
                arrowprops={"arrowstyle": "-", "color": _GAP_COLOUR, "lw": 0.7},
                **style,
            )
            box = _text_box(label, renderer)
        placed.append(label)
        boxes.append(box)
    return placed


def gsd_target_cm(result: CheckResult) -> tuple[float, str] | None:
    """The GSD the map's colour scale is anchored on, and what it is: the plan's, else the
    block's median; None without a GSD."""
    if result.plan is not None:
        return float(result.plan.planned.summary.gsd_cm), "planned"
    finite = result.gsd_cm[np.isfinite(result.gsd_cm)] if result.gsd_cm.size else result.gsd_cm
    if finite.size == 0:
        return None
    return float(np.median(finite)), "median"


def gsd_png(result: CheckResult) -> bytes:
    """Finest GSD seeing each cell (cm): :func:`gsd_map` as PNG."""
    return gsd_map(result).png()


def gsd_map(result: CheckResult) -> _Map:
    """Finest GSD seeing each cell (cm), on a diverging scale centred on the target GSD and
    spanning the tolerance (white at the target, blue finer, red coarser, beyond it the ends)."""
    m = _Map(result, "Ground sample distance (finest view), cm")
    target = gsd_target_cm(result)
    if result.gsd_cm_raster is not None and np.isfinite(result.gsd_cm_raster).any() and target is not None:
        gsd, what = target
        low, high = gsd * (1 - GSD_TOLERANCE), gsd * (1 + GSD_TOLERANCE)
        image = _draw_raster(
            m, result.gsd_cm_raster, np.zeros(result.in_area.shape, dtype=bool), cmap="RdBu_r", vmin=low,
            vmax=high,
        )  # fmt: skip
        bar = m.figure.colorbar(image, ax=m.ax, shrink=0.9, extend="both", ticks=[low, gsd, high])
        pct = round(GSD_TOLERANCE * 100)
        bar.ax.set_yticklabels([f"{low:.2f} (-{pct} %)", f"{gsd:.2f} {what}", f"{high:.2f} (+{pct} %)"])
        bar.set_label("GSD, cm per pixel", fontsize=9)
    else:
        m.ax.text(0.5, 0.5, "no GSD raster", transform=m.ax.transAxes, ha="center")
    m.area_outline()
    m.centres()
    return m


def base_height_png(result: CheckResult) -> bytes:
    """:func:`base_height_map` as PNG."""
    return base_height_map(result).png()


def base_height_map(result: CheckResult) -> _Map:
    """The best pair seeing each cell, in three classes of base-height ratio (weak, good,
    wide); the pairs are those the stereo share counts (``result.stereo.good_pair_basis``: frames on
    one line or neighbouring lines when there are any)."""
    t = result.thresholds
    m = _Map(
        result,
        f"Base-height ratio of the best pair ({result.stereo.good_pair_basis}; good "
        f"{t.min_base_height_ratio:g}-{t.max_base_height_ratio:g})",
    )
    classes = result.stereo.stereo_class.astype(np.float64)
    if (result.stereo.stereo_class != STEREO_NONE).any():
        colours = {STEREO_WEAK: "#fb8c00", STEREO_GOOD: "#43a047", STEREO_WIDE: "#8e24aa"}
        codes = sorted(colours)
        cmap = ListedColormap([colours[c] for c in codes])
        norm = BoundaryNorm([c - 0.5 for c in codes] + [codes[-1] + 0.5], cmap.N)
        image = _draw_raster(m, classes, result.stereo.stereo_class == STEREO_NONE, cmap=cmap, norm=norm)
        bar = m.figure.colorbar(image, ax=m.ax, shrink=0.8, ticks=codes)
        labels = {
            STEREO_WEAK: f"weak\nB/H < {t.min_base_height_ratio:g}",
            STEREO_GOOD: "good",
            STEREO_WIDE: f"wide\nB/H > {t.max_base_height_ratio:g}",
        }
        bar.ax.set_yticklabels([labels[c] for c in codes])
        bar.set_label("best overlapping pair", fontsize=9)
    else:
        m.ax.text(0.5, 0.5, "no overlapping pair", transform=m.ax.transAxes, ha="center")
    m.area_outline()
    m.centres()
    return m
