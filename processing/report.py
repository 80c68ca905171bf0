"""The check's report folder: one page a person reads on a laptop in the field, and its data.

Files (written together, all or nothing, by :func:`write_report`):

- report.html: the verdict first (pass or fail, with the reasons), the key figures, four maps
  (views per cell, gaps, GSD, base-height ratio), the gaps table and the flagged frames; it
  loads the PNGs next to it, nothing from the network.
- view_count.png, gaps.png, gsd.png, base_height.png: the maps, in metres east and north of
  the area's south-west corner in the check's UTM frame, equal aspect, with a scale bar.
- report.json: the same figures for programs (:meth:`CheckResult.as_dict`).
- coverage.tif: views per cell (GeoTIFF, the check's UTM CRS; opens in QGIS).
- gaps.geojson: one polygon per gap (WGS84), with its index and area.
- footprints.geojson: one polygon per frame (WGS84), with its name, height and GSD.

matplotlib is used through ``Figure`` and the Agg canvas, never pyplot (no global state).
"""

from __future__ import annotations

import html
import io
import itertools
import json
import logging
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch, Rectangle
from matplotlib.text import Text as MplText
from numpy.typing import NDArray
from pyproj import CRS
from shapely.geometry import Polygon, mapping
from shapely.geometry.polygon import orient

from planner.mapplot import polygon_path, scale_bar_length_m
from planner.outputs import atomic_write_bytes, atomic_write_text, staged_output_dir
from planner.plan import SurveyPlan

from .check import STEREO_GOOD, STEREO_NONE, STEREO_WEAK, STEREO_WIDE, CheckResult, Distribution

log = logging.getLogger(__name__)

REPORT_FILES = (
    "report.html",
    "report.json",
    "coverage.tif",
    "gaps.geojson",
    "footprints.geojson",
    "view_count.png",
    "gaps.png",
    "gsd.png",
    "base_height.png",
)

#: View-count classes of the map: lower bounds and colours (red: unseen ... dark green: 9+).
VIEW_CLASSES = (0, 1, 2, 3, 5, 9)
VIEW_COLOURS = ("#d32f2f", "#fb8c00", "#fdd835", "#c5e1a5", "#66bb6a", "#1b5e20")
_GAP_COLOUR = "#d32f2f"
_FIGSIZE_IN = (7.0, 6.0)
_DPI = 110


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
        self.figure = Figure(figsize=_FIGSIZE_IN, dpi=_DPI, layout="constrained")
        FigureCanvasAgg(self.figure)
        self.ax = self.figure.add_subplot()
        self.ax.set_title(title, fontsize=12, loc="left")
        self.ax.set_aspect("equal")
        self.ax.set_xlim(self.limits[0], self.limits[1])
        self.ax.set_ylim(self.limits[2], self.limits[3])
        self.ax.set_xlabel("metres east", fontsize=9)
        self.ax.set_ylabel("metres north", fontsize=9)
        self.ax.tick_params(labelsize=8)
        self.ax.set_facecolor("#f5f5f5")

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
        x0, x1, y0, y1 = self.limits
        length = scale_bar_length_m(x1 - x0)
        unit = (y1 - y0) / 100.0
        right = x1 - 4.0 * unit
        left = right - length
        bottom = y0 + 3.0 * unit
        self.ax.add_patch(
            Rectangle(
                (left - 2 * unit, bottom - 1.5 * unit),
                length + 4 * unit,
                6.5 * unit,
                facecolor="white",
                edgecolor="#424242",
                lw=0.6,
                alpha=0.9,
                zorder=9,
            )
        )
        self.ax.plot([left, right], [bottom, bottom], color="black", lw=3, zorder=10, solid_capstyle="butt")
        label = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
        self.ax.text(
            (left + right) / 2,
            bottom + 1.2 * unit,
            label,
            ha="center",
            va="bottom",
            fontsize=9,
            zorder=10,
        )

    def png(self) -> bytes:
        self.scale_bar()
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


def gsd_png(result: CheckResult) -> bytes:
    """Finest GSD seeing each cell (cm)."""
    m = _Map(result, "Ground sample distance (finest view), cm")
    if result.gsd_cm_raster is not None and np.isfinite(result.gsd_cm_raster).any():
        image = _draw_raster(
            m, result.gsd_cm_raster, np.zeros(result.in_area.shape, dtype=bool), cmap="viridis"
        )
        bar = m.figure.colorbar(image, ax=m.ax, shrink=0.8)
        bar.set_label("GSD, cm per pixel", fontsize=9)
    else:
        m.ax.text(0.5, 0.5, "no GSD raster", transform=m.ax.transAxes, ha="center")
    m.area_outline()
    m.centres()
    return m.png()


def base_height_png(result: CheckResult) -> bytes:
    """The best pair seeing each cell, in three classes of base-height ratio (weak, good,
    wide); the pairs are those the stereo share counts (``result.good_pair_basis``: frames on
    one line or neighbouring lines when there are any)."""
    t = result.thresholds
    m = _Map(
        result,
        f"Base-height ratio of the best pair ({result.good_pair_basis}; good "
        f"{t.min_base_height_ratio:g}-{t.max_base_height_ratio:g})",
    )
    classes = result.stereo_class.astype(np.float64)
    if (result.stereo_class != STEREO_NONE).any():
        colours = {STEREO_WEAK: "#fb8c00", STEREO_GOOD: "#43a047", STEREO_WIDE: "#8e24aa"}
        codes = sorted(colours)
        cmap = ListedColormap([colours[c] for c in codes])
        norm = BoundaryNorm([c - 0.5 for c in codes] + [codes[-1] + 0.5], cmap.N)
        image = _draw_raster(m, classes, result.stereo_class == STEREO_NONE, cmap=cmap, norm=norm)
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
    return m.png()


# --- vector files ----------------------------------------------------------------------------


def _feature_collection(name: str, features: Sequence[dict[str, Any]]) -> str:
    return (
        json.dumps({"type": "FeatureCollection", "name": name, "features": list(features)}, allow_nan=False)
        + "\n"
    )


def _rounded(geom: Polygon) -> dict[str, Any]:
    ring = orient(geom, sign=1.0)
    data: dict[str, Any] = mapping(ring)
    data["coordinates"] = [[[round(x, 8), round(y, 8)] for x, y in r] for r in data["coordinates"]]
    return data


def gaps_geojson(result: CheckResult) -> str:
    """One Polygon feature per gap (WGS84 lon/lat), properties ``gap`` (index) and ``area_m2``."""
    return _feature_collection(
        "gaps",
        [
            {
                "type": "Feature",
                "geometry": _rounded(g.polygon_lonlat),
                "properties": {"gap": g.index, "area_m2": round(g.area_m2, 2)},
            }
            for g in result.gaps
        ],
    )


def footprints_geojson(result: CheckResult) -> str:
    """One Polygon feature per frame (WGS84), properties ``name``, ``height_agl_m``, ``gsd_cm``."""
    features = []
    rings = result.footprints_lonlat
    for k, name in enumerate(result.frames.name):
        ring = np.vstack([rings[k], rings[k][:1]])
        poly = Polygon(ring)
        if poly.is_empty or poly.area == 0:
            continue
        gsd = float(result.gsd_cm[k])
        features.append(
            {
                "type": "Feature",
                "geometry": _rounded(poly),
                "properties": {
                    "name": name,
                    "height_agl_m": round(float(result.height_agl_m[k]), 2),
                    "gsd_cm": round(gsd, 3) if math.isfinite(gsd) else None,
                },
            }
        )
    return _feature_collection("footprints", features)


def _json_clean(value: Any) -> Any:
    """JSON has no NaN: None instead; numpy scalars and arrays as Python values."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _json_clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _json_clean(value.tolist())
    if isinstance(value, np.generic):
        return _json_clean(value.item())
    return value


def report_json(result: CheckResult) -> str:
    """report.json: :meth:`CheckResult.as_dict` with NaN as null."""
    return json.dumps(_json_clean(result.as_dict()), indent=2, allow_nan=False) + "\n"


# --- the page ------------------------------------------------------------------------------------

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 62em; color: #212121;
       padding: 0 1em; line-height: 1.4; }
.verdict { padding: 0.8em 1.2em; border-radius: 6px; color: white; margin-bottom: 1em; }
.verdict h1 { margin: 0; font-size: 2em; }
.pass { background: #2e7d32; } .fail { background: #c62828; }
.verdict ul { margin: 0.4em 0 0 0; font-size: 1.05em; }
.warn { background: #fff8e1; border-left: 5px solid #f9a825; padding: 0.5em 1em; margin: 1em 0; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; }
td, th { border-bottom: 1px solid #e0e0e0; padding: 0.25em 0.8em; text-align: left;
         vertical-align: top; }
th { background: #f5f5f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.maps { display: grid; grid-template-columns: repeat(auto-fit, minmax(28em, 1fr)); gap: 1em; }
.maps img { width: 100%; border: 1px solid #e0e0e0; }
.small { color: #616161; font-size: 0.9em; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _table(headers: Sequence[str], rows: Sequence[Sequence[object]], numeric: Sequence[bool] = ()) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = []
    for row in rows:
        cells = []
        for k, value in enumerate(row):
            cls = ' class="num"' if k < len(numeric) and numeric[k] else ""
            cells.append(f"<td{cls}>{_e(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _dist_row(label: str, dist: Distribution | None, fmt: str, unit: str) -> list[object]:
    if dist is None:
        return [label, "-", "-", "-", "-", "-", 0]
    return [
        label,
        *(f"{getattr(dist, k):{fmt}}{unit}" for k in ("min", "p10", "median", "p90", "max")),
        dist.count,
    ]


def report_html(result: CheckResult, *, refly: SurveyPlan | None = None) -> str:
    """The page (see the module docstring); PNGs are referenced by file name."""
    verdict = "PASS" if result.passed else "FAIL"
    cls = "pass" if result.passed else "fail"
    title = f"sfap check: {verdict}"
    if result.plan is not None:
        title += f" - {result.plan.name}"
    reasons = "".join(f"<li>{_e(r)}</li>" for r in result.reasons)
    verdict_html = (
        f'<div class="verdict {cls}"><h1>{verdict}</h1>'
        + (f"<ul>{reasons}</ul>" if reasons else "<div>every threshold is met</div>")
        + "</div>"
    )
    warnings = "".join(f"<li>{_e(w)}</li>" for w in result.warnings)
    warn_html = f'<div class="warn"><b>Warnings</b><ul>{warnings}</ul></div>' if warnings else ""
    figures = _table(["figure", "value"], result.key_figures())
    coverage_rows = [
        [f">= {k} frame{'s' if k > 1 else ''}", f"{v:.1f} %"] for k, v in result.seen_pct.items()
    ]
    coverage = _table(["share of the area seen by", ""], coverage_rows, numeric=[False, True])
    dists = _table(
        ["distribution", "min", "10 %", "median", "90 %", "max", "count"],
        [
            _dist_row("forward overlap", result.forward_overlap_pct, ".0f", " %"),
            _dist_row("side overlap", result.side_overlap_pct, ".0f", " %"),
            _dist_row("B/H, consecutive frames of a line", result.base_height_along_line, ".2f", ""),
            _dist_row("B/H, neighbouring lines", result.base_height_across_lines, ".2f", ""),
            _dist_row(
                "B/H, every overlapping pair", Distribution.of(result.pair_base_height_ratio), ".2f", ""
            ),
            _dist_row(
                "pair intersection angle",
                Distribution.of(result.pair_intersection_deg),
                ".1f",
                " deg",
            ),
            _dist_row("GSD", Distribution.of(result.gsd_cm), ".2f", " cm"),
            _dist_row("height above ground", Distribution.of(result.height_agl_m), ".1f", " m"),
            _dist_row(
                "ground speed",
                Distribution.of(result.speed_m_s) if result.speed_m_s is not None else None,
                ".1f",
                " m/s",
            ),
            _dist_row(
                "motion blur",
                Distribution.of(result.blur_px) if result.blur_px is not None else None,
                ".2f",
                " px",
            ),
        ],
        numeric=[False, True, True, True, True, True, True],
    )
    if result.gaps:
        gap_rows = [
            [g.index, f"{g.area_m2:,.0f}", f"{g.centroid_lat_deg:.6f}", f"{g.centroid_lon_deg:.6f}"]
            for g in result.gaps
        ]
        gaps = _table(
            ["gap", "area m2", "centre lat deg", "centre lon deg"],
            gap_rows,
            [True, True, True, True],
        )
    else:
        gaps = "<p>No gap: every part of the area is seen by at least one frame.</p>"
    if result.flagged:
        flagged = _table(["frame", "flag", "detail"], [[f.name, f.kind, f.detail] for f in result.flagged])
    else:
        flagged = "<p>No frame flagged.</p>"
    if result.left_out:
        left_out = "<h2>Frames left out</h2>" + _table(
            ["frame", "why"], [list(item) for item in result.left_out]
        )
    else:
        left_out = ""
    notes = "".join(f"<li>{_e(n)}</li>" for n in result.notes)
    thresholds = ", ".join(f"{k} = {v:g}" for k, v in result.thresholds.as_dict().items())
    refly_html = ""
    if refly is not None:
        su = refly.summary
        refly_html = (
            "<h2>Re-fly mission</h2>"
            f"<p>refly/mission.plan (QGroundControl) and refly/mission.waypoints: {su.photo_count} photos "
            f"on {su.line_count} line(s) at {su.altitude_agl_m:.1f} m above ground, "
            f"{su.flight_distance_m:,.0f} m, about {su.flight_time_s / 60:.0f} min; map in "
            "refly/map.png.</p>"
        )
    maps = "".join(
        f'<figure><img src="{name}" alt="{_e(alt)}"></figure>'
        for name, alt in (
            ("view_count.png", "views per ground cell"),
            ("gaps.png", "gaps"),
            ("gsd.png", "ground sample distance"),
            ("base_height.png", "base-height ratio"),
        )
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_e(title)}</title><style>{_CSS}</style></head>
<body>
{verdict_html}
{warn_html}
<h2>Key figures</h2>
{figures}
<h2>Maps</h2>
<div class="maps">{maps}</div>
<h2>Coverage</h2>
{coverage}
<h2>Gaps</h2>
{gaps}
<p class="small">Polygons in gaps.geojson; views per cell in coverage.tif (open both in QGIS).</p>
<h2>Overlap, stereo, GSD and blur</h2>
{dists}
{refly_html}
<h2>Flagged frames</h2>
{flagged}
{left_out}
<h2>How this was computed</h2>
<ul><li>ground: {_e(result.ground_description)}</li><li>area: {_e(result.area_source)}</li>
{notes}</ul>
<p class="small">Thresholds: {_e(thresholds)}.
Full figures in report.json.</p>
</body></html>
"""


#: coverage.tif's value outside the area judged (0 inside means no frame sees the cell).
COVERAGE_NODATA = -1


def write_coverage_tif(result: CheckResult, path: str | os.PathLike[str]) -> Path:
    """coverage.tif: frames that see each cell, int32, ``COVERAGE_NODATA`` outside the area, in
    the UTM zone's EPSG code when the area lies in one zone (resampled, nearest, same cell size),
    else in the check's own transverse Mercator frame; the band is described."""
    from .coverage import utm_epsg, write_geotiff

    counts = np.where(result.in_area, result.view_count, COVERAGE_NODATA).astype(np.int32)
    west, south, east, north = result.area_lonlat.bounds
    epsg = utm_epsg(west, south, east, north)
    return write_geotiff(
        path,
        counts,
        result.grid,
        nodata=COVERAGE_NODATA,
        description="views: frames that see the cell (0 = gap; nodata outside the area judged)",
        to_crs=CRS.from_epsg(epsg) if epsg is not None else None,
    )


def write_report(
    result: CheckResult,
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    refly: SurveyPlan | None = None,
) -> list[Path]:
    """Write every report file (module docstring) into ``out_dir``, all or nothing; with
    ``refly``, that mission's files (``sfap plan``'s set) into ``out_dir/refly``."""
    from planner.plan_folder import OUTPUT_FILES, write_outputs

    final = Path(out_dir)
    with staged_output_dir(final, overwrite=overwrite) as staging:
        atomic_write_bytes(staging / "view_count.png", view_count_png(result))
        atomic_write_bytes(staging / "gaps.png", gaps_png(result))
        atomic_write_bytes(staging / "gsd.png", gsd_png(result))
        atomic_write_bytes(staging / "base_height.png", base_height_png(result))
        write_coverage_tif(result, staging / "coverage.tif")
        atomic_write_text(staging / "gaps.geojson", gaps_geojson(result))
        atomic_write_text(staging / "footprints.geojson", footprints_geojson(result))
        atomic_write_text(staging / "report.json", report_json(result))
        atomic_write_text(staging / "report.html", report_html(result, refly=refly))
        if refly is not None:
            write_outputs(refly, staging / "refly")
    written = [final / name for name in REPORT_FILES]
    if refly is not None:
        written += [final / "refly" / name for name in OUTPUT_FILES]
    return written
