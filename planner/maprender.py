"""map.png drawn with Pillow: the map of :func:`planner.mapplot.render_map_figure`, at a fraction
of the cost, read at its scale (issue 24): footprints and stations only when they can be told
apart (:func:`planner.maplayout.simplification`; else the legend says what was left out and which
file has it), one colour per pass group (:func:`planner.maplayout.pass_styles`), and a plan's
sorties as outlines with their numbers. The matplotlib figure keeps the simpler drawing.

matplotlib costs about 0.3 s to import and 0.2-0.3 s to draw and encode this map, more than
planning and writing every other output of a small plan together; Pillow imports in about
0.01 s. The map box and the legend are drawn at twice their size and reduced (anti-aliasing),
the margins' texts and axes at the PNG's own size (FreeType anti-aliases text at any size; drawn
at twice it, the margins were half the page's pixels to fill, clear, draw and reduce), in the
same page layout (:func:`planner.mapplot.map_frame`), colours, legend, header and caption texts
as the matplotlib figure, and saved as a 256-colour PNG.

Sizes are given in points (1/72 inch) as in matplotlib, and turned into pixels at the PNG's dpi.
"""

from __future__ import annotations

import importlib.util
import io
import logging
import math
import os
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageChops, ImageDraw, ImageFont
from shapely.geometry import MultiPolygon, Polygon

from .errors import InputError
from .kinds import PassKind
from .maplayout import AREA_EDGE as _AREA_EDGE
from .maplayout import AREA_FACE as _AREA_FACE
from .maplayout import (
    DEFAULT_MAX_STATIONS,
    MapFrame,
    map_frame,
    pass_styles,
    scale_bar_length_m,
    simplification,
)
from .maplayout import EXCLUSION_COLOUR as _EXCLUSION
from .maplayout import PASS_COLOURS as _PASS_COLOURS
from .maplayout import shown_text as _shown
from .maplayout import thin as _thin
from .mapview import MapPlan, MapStations
from .outputs import atomic_write_bytes
from .stats import median

log = logging.getLogger(__name__)

_SUPERSAMPLE = 2
_Colour = tuple[int, int, int] | tuple[int, int, int, int]


def _rgb(hex_colour: str, alpha: float | None = None) -> _Colour:
    r, g, b = (int(hex_colour[i : i + 2], 16) for i in (1, 3, 5))
    return (r, g, b) if alpha is None else (r, g, b, round(255 * alpha))


def _font_dirs() -> list[Path]:
    dirs = []
    spec = importlib.util.find_spec("matplotlib")  # finds the package without importing it
    if spec is not None and spec.submodule_search_locations:
        dirs.append(Path(next(iter(spec.submodule_search_locations))) / "mpl-data" / "fonts" / "ttf")
    dirs.append(Path("/usr/share/fonts/truetype/dejavu"))
    return dirs


@lru_cache(maxsize=32)
def _font(size_px: int, bold: bool = False) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
    for folder in _font_dirs():
        if (folder / name).exists():
            return ImageFont.truetype(str(folder / name), size_px)
    return ImageFont.load_default(size=size_px)  # Pillow's own scalable font


#: The text sizes (points) and weights the map is written in (:func:`draw_map`), by the resolution
#: they are drawn at: the margins' at the PNG's, the map box's and the legend's supersampled.
_TEXT_SIZES = {
    1: ((14.0, True), (10.0, False), (8.0, False)),
    _SUPERSAMPLE: ((13.0, True), (9.0, False), (8.0, False)),
}


def prepare(dpi: int = 130) -> None:
    """Load what :func:`draw_map` and the PNG writer need and would load on first use: Pillow's
    file formats (``Image.preinit``: PNG among them) and the fonts of a map of ``dpi``. For a
    helper that gets ready while the plan is still being made (planner.aside)."""
    Image.preinit()
    for supersample, sizes in _TEXT_SIZES.items():
        for size_pt, bold in sizes:
            _font(round(size_pt * dpi * supersample / 72.0), bold)
    _font(round(10.0 * dpi / 72.0))  # the y axis label's (its own cache entry)


def _nice_ticks(low: float, high: float, max_ticks: int = 9) -> list[float]:
    """Round tick positions in [low, high]: steps of 1, 2, 2.5 or 5 x 10^n, at most max_ticks."""
    span = high - low
    if not (span > 0 and math.isfinite(span)):
        return []
    raw = span / max_ticks
    exponent = math.floor(math.log10(raw))
    for mantissa in (1.0, 2.0, 2.5, 5.0, 10.0):
        step = mantissa * 10.0**exponent
        if span / step <= max_ticks:
            break
    first = math.ceil(low / step)
    return [k * step for k in range(first, math.floor(high / step) + 1)]


def _tick_label(value: float) -> str:
    text = f"{value:.6g}"
    return "0" if text in ("-0", "0") else text


def _page_size(frame: MapFrame, dpi: int, supersample: int) -> tuple[int, int]:
    """The page's pixels at ``supersample`` (1 or :data:`_SUPERSAMPLE`): at 1, the supersampled
    page's reduced (its odd last row or column kept)."""
    width, height = round(frame.fig_w_in * dpi * _SUPERSAMPLE), round(frame.fig_h_in * dpi * _SUPERSAMPLE)
    if supersample == _SUPERSAMPLE:
        return width, height
    return -(-width // _SUPERSAMPLE), -(-height // _SUPERSAMPLE)


def _supersampled(
    left: float, top: float, right: float, bottom: float
) -> tuple[tuple[int, int], tuple[int, int, int, int]]:
    """A region of the page (PNG pixels) widened to whole pixels: its corner on the page, and the
    region of a supersampled canvas that reduces onto it pixel for pixel."""
    x0, y0, x1, y1 = math.floor(left), math.floor(top), math.ceil(right), math.ceil(bottom)
    k = _SUPERSAMPLE
    return (x0, y0), (k * x0, k * y0, k * x1, k * y1)


class _Page:
    """A white canvas of the map's page with its map transform: the whole page, or a region of it
    (``region``: left, top, right and bottom, in this canvas's pixels from the page's corner), at
    ``supersample`` times the PNG's resolution. Coordinates on it (``left``, ``top``, :meth:`xy`)
    are the canvas's own."""

    def __init__(
        self, frame: MapFrame, dpi: int, supersample: int, region: tuple[int, int, int, int] | None = None
    ) -> None:
        self.frame, self.dpi = frame, dpi
        self.px_per_in = dpi * supersample
        self.px_per_pt = self.px_per_in / 72.0
        f = frame
        x_at, y_at, right, bottom = region if region is not None else (0, 0, *_page_size(f, dpi, supersample))
        self.width, self.height = right - x_at, bottom - y_at
        self.image = Image.new("RGB", (self.width, self.height), "white")
        self.draw = ImageDraw.Draw(self.image)
        self.left = f.left_in * self.px_per_in - x_at
        self.top = f.top_in * self.px_per_in - y_at
        self.map_w = f.map_w_in * self.px_per_in
        self.map_h = f.map_h_in * self.px_per_in
        x0, x1, _y0, y1 = f.limits
        self.x0, self.y1 = x0, y1
        self.scale = self.map_w / (x1 - x0)  # px per metre, equal in x and y

    @property
    def box(self) -> tuple[float, float, float, float]:
        """The map box: left, top, right, bottom."""
        return (self.left, self.top, self.left + self.map_w, self.top + self.map_h)

    def pt(self, points: float) -> float:
        return points * self.px_per_pt

    def xy(self, x_m: Any, y_m: Any) -> tuple[Any, Any]:
        """Metres from home (scalars or arrays) to page pixels."""
        return self.left + (np.asarray(x_m) - self.x0) * self.scale, self.top + (
            self.y1 - np.asarray(y_m)
        ) * self.scale

    def points(self, xy_m: np.ndarray) -> list[tuple[float, float]]:
        px, py = self.xy(xy_m[:, 0], xy_m[:, 1])
        return list(zip(px.tolist(), py.tolist(), strict=True))

    def text(
        self,
        xy: tuple[float, float],
        text: str,
        size_pt: float,
        *,
        anchor: str = "la",
        bold: bool = False,
        fill: str = "#000000",
    ) -> None:
        font = _font(round(self.pt(size_pt)), bold)
        lines = text.split("\n")
        step = self.pt(size_pt) * 1.2
        for k, line in enumerate(lines):
            self.draw.text((xy[0], xy[1] + k * step), line, font=font, fill=fill, anchor=anchor)

    def marker(
        self, x: float, y: float, kind: str, size_pt: float, face: str, edge: str, edge_pt: float
    ) -> None:
        r = self.pt(size_pt) / 2
        if kind == "^":
            shape = [(x, y - r), (x + r * 0.95, y + r * 0.75), (x - r * 0.95, y + r * 0.75)]
            self.draw.polygon(shape, fill=face, outline=edge, width=max(1, round(self.pt(edge_pt))))
        else:
            self.draw.ellipse(
                (x - r, y - r, x + r, y + r), fill=face, outline=edge, width=max(1, round(self.pt(edge_pt)))
            )

    def arrow(
        self,
        start: tuple[float, float],
        end: tuple[float, float],
        colour: str,
        width_pt: float,
        head_pt: float,
    ) -> None:
        dx, dy = end[0] - start[0], end[1] - start[1]
        length = math.hypot(dx, dy) or 1.0
        ux, uy = dx / length, dy / length
        head = self.pt(head_pt)
        base = (end[0] - ux * head, end[1] - uy * head)
        self.draw.line([start, base], fill=colour, width=max(1, round(self.pt(width_pt))))
        half = head * 0.45
        self.draw.polygon(
            [end, (base[0] - uy * half, base[1] + ux * half), (base[0] + uy * half, base[1] - ux * half)],
            fill=colour,
        )


def _fill_polygon(
    page: _Page,
    geom: Polygon | MultiPolygon,
    ox: float,
    oy: float,
    colour: str,
    hatch_pt: float | None = None,
) -> None:
    """Fill a polygon with holes: a mask over its bounding box only, holes cut out of it;
    with ``hatch_pt`` only diagonal hatching of that spacing is drawn."""
    parts = [g for g in (geom.geoms if isinstance(geom, MultiPolygon) else [geom]) if not g.is_empty]
    if not parts:
        return
    rings = [
        [page.points(np.asarray(r.coords) - (ox, oy)) for r in (g.exterior, *g.interiors)] for g in parts
    ]
    xs = [x for part in rings for x, _ in part[0]]
    ys = [y for part in rings for _, y in part[0]]
    left, top = max(0, math.floor(min(xs))), max(0, math.floor(min(ys)))
    right, bottom = min(page.width, math.ceil(max(xs)) + 1), min(page.height, math.ceil(max(ys)) + 1)
    if right <= left or bottom <= top:
        return
    # The mask is 0 or 255 (polygons are drawn without anti-aliasing): as a "1" image Pillow
    # copies the colour where it is set instead of blending every pixel, the same pixels 10x
    # faster. Hatching multiplies two masks, which wants "L".
    mask = Image.new("L" if hatch_pt is not None else "1", (right - left, bottom - top), 0)
    draw = ImageDraw.Draw(mask)
    for part in rings:
        for k, ring in enumerate(part):
            draw.polygon([(x - left, y - top) for x, y in ring], fill=255 if k == 0 else 0)
    if hatch_pt is not None:
        hatch = Image.new("L", mask.size, 0)
        hatch_draw = ImageDraw.Draw(hatch)
        spacing = max(3, round(page.pt(hatch_pt)))
        h = mask.height
        for k in range(-h - (left + top) % spacing, mask.width, spacing):
            hatch_draw.line([(k, h), (k + h, 0)], fill=255, width=max(1, round(page.pt(0.7))))
        mask = ImageChops.multiply(mask, hatch)
    page.image.paste(colour, (left, top, right, bottom), mask=mask)


def _outline(
    page: _Page, geom: Polygon | MultiPolygon, ox: float, oy: float, colour: str, width_pt: float
) -> None:
    parts = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    width = max(1, round(page.pt(width_pt)))
    for part in parts:
        if part.is_empty:
            continue
        for ring in (part.exterior, *part.interiors):
            page.draw.line(
                page.points(np.asarray(ring.coords) - (ox, oy)), fill=colour, width=width, joint="curve"
            )


def _dashed(points: np.ndarray, on_px: float, off_px: float) -> list[list[tuple[float, float]]]:
    """Dashes of ``on_px`` separated by ``off_px`` along a polyline (pixels), each as its two
    ends (a dash is a few points long, so one that turns a corner is drawn as its chord)."""
    seg = np.diff(points, axis=0)
    along = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    total = float(along[-1])
    if total <= 0:
        return []
    starts = np.arange(0.0, total, on_px + off_px)
    stops = np.minimum(starts + on_px, total)
    x0, y0 = np.interp(starts, along, points[:, 0]), np.interp(starts, along, points[:, 1])
    x1, y1 = np.interp(stops, along, points[:, 0]), np.interp(stops, along, points[:, 1])
    return [
        [(a, b), (c, d)]
        for a, b, c, d in zip(x0.tolist(), y0.tolist(), x1.tolist(), y1.tolist(), strict=True)
    ]


def _legend_height_pt(labels: Sequence[str], size_pt: float, gap_pt: float) -> float:
    """The legend's height (points) from its top: its rows of text, their gaps, and room below the
    last line for its descenders."""
    return 4 + sum(size_pt * 1.2 * (label.count("\n") + 1) + gap_pt for label in labels) + size_pt


def _legend(sheet: _Page, entries: Sequence[tuple[str, dict[str, Any]]]) -> None:
    """Legend to the right of the map box: a handle (patch, line or marker) and its label, drawn
    supersampled on a canvas of its own (its markers anti-aliased) and reduced onto ``sheet``."""
    size_pt, gap_pt = 8.0, 5.0
    # wrapped to the legend's width (3.4 in of page: about 44 characters at 8 pt)
    rows = [
        ("\n".join(textwrap.fill(line, 44, subsequent_indent="  ") for line in label.split("\n")), style)
        for label, style in entries
    ]
    height_pt = _legend_height_pt([label for label, _ in rows], size_pt, gap_pt)
    f = sheet.frame
    start_in = f.left_in + f.map_w_in + 0.01 * f.fig_w_in
    corner, region = _supersampled(
        start_in * sheet.dpi,
        f.top_in * sheet.dpi,
        sheet.width,
        min(sheet.height, (f.top_in + height_pt / 72) * sheet.dpi),
    )
    page = _Page(f, sheet.dpi, _SUPERSAMPLE, region)
    x = page.left + page.map_w + page.pt(0.01 * f.fig_w_in * 72) + page.pt(8)
    y = page.top + page.pt(4)
    line_h = page.pt(size_pt * 1.2)
    handle_w = page.pt(20)
    for label, style in rows:
        centre_y = y + line_h / 2
        kind = style["kind"]
        if kind == "patch":
            box = (x, centre_y - page.pt(3.5), x + handle_w, centre_y + page.pt(3.5))
            if style.get("face"):
                page.draw.rectangle(box, fill=style["face"])
            if style.get("hatch"):
                for k in range(0, round(handle_w), max(2, round(page.pt(4)))):
                    page.draw.line(
                        [(box[0] + k, box[3]), (min(box[2], box[0] + k + (box[3] - box[1])), box[1])],
                        fill=style["edge"],
                        width=1,
                    )
            page.draw.rectangle(
                box, outline=style["edge"], width=max(1, round(page.pt(style.get("lw", 1.0))))
            )
        elif kind == "line":
            width = max(1, round(page.pt(style["lw"])))
            if style.get("dashed"):
                pts = np.array([[x, centre_y], [x + handle_w, centre_y]])
                for dash in _dashed(pts, page.pt(4), page.pt(3)):
                    page.draw.line(dash, fill=style["colour"], width=width)
            else:
                page.draw.line([(x, centre_y), (x + handle_w, centre_y)], fill=style["colour"], width=width)
        elif kind == "note":  # a sentence on what the map leaves out, no handle
            pass
        else:
            page.marker(
                x + handle_w / 2,
                centre_y,
                style["marker"],
                style["ms"],
                style["face"],
                style["edge"],
                style.get("mew", 0.5),
            )
        page.text((x + handle_w + page.pt(8), y), label, size_pt)
        y += line_h * (label.count("\n") + 1) + page.pt(gap_pt)
    sheet.image.paste(page.image.reduce(_SUPERSAMPLE), corner)


def _axes(page: _Page, xticks: Sequence[float], yticks: Sequence[float]) -> None:
    """The map box's frame, its ticks and their labels (metres), and the axes' names."""
    box = page.box
    page.draw.rectangle(box, outline="#000000", width=max(1, round(page.pt(0.8))))
    tick_len, tick_w = page.pt(3.5), max(1, round(page.pt(0.8)))
    for t in xticks:
        px = float(page.xy(t, 0.0)[0])
        page.draw.line([(px, box[3]), (px, box[3] + tick_len)], fill="#000000", width=tick_w)
        page.text((px, box[3] + tick_len + page.pt(2)), _tick_label(t), 10, anchor="ma")
    for t in yticks:
        py = float(page.xy(0.0, t)[1])
        page.draw.line([(box[0] - tick_len, py), (box[0], py)], fill="#000000", width=tick_w)
        page.text((box[0] - tick_len - page.pt(2), py), _tick_label(t), 10, anchor="rm")
    page.text(((box[0] + box[2]) / 2, box[3] + page.pt(20)), "metres east of home (grid)", 10, anchor="ma")
    ylabel = "metres north of home (grid)"
    font = _font(round(page.pt(10)))
    label_box = font.getbbox(ylabel)
    label = Image.new("L", (int(label_box[2]) + 4, int(page.pt(14))), 0)
    ImageDraw.Draw(label).text((2, 0), ylabel, font=font, fill=255)
    label = label.rotate(90, expand=True)
    widest = max((font.getbbox(_tick_label(t))[2] for t in yticks), default=0)
    lx = int(box[0] - tick_len - page.pt(6) - widest - label.width)
    ly = int((box[1] + box[3]) / 2 - label.height / 2)
    page.image.paste("#000000", (lx, ly), mask=label)


_SORTIE_EDGE = "#37474f"


def _draw_sorties(
    page: _Page, sorties: Sequence[MapStations], ox: float, oy: float, colour_of_pass: dict[int, str]
) -> None:
    """Each sortie as the outline of its stations (their convex hull: a strip of its lines) in the
    colour of the pass it flies, and its number in a disc where it starts (its first station), so
    that the strips of one pass read side by side and the numbers of different passes apart."""
    from shapely import MultiPoint

    width = max(1, round(page.pt(1.0)))
    layer = ImageDraw.Draw(page.image, "RGBA")
    labels: list[tuple[float, float, int, str]] = []
    for number, st in enumerate(sorties, start=1):
        if len(st) == 0:
            continue
        colour = colour_of_pass.get(int(st.pass_index[0]), _SORTIE_EDGE)
        hull = MultiPoint(np.column_stack([st.x_m - ox, st.y_m - oy])).convex_hull
        if hull.geom_type == "Polygon":
            ring = np.asarray(hull.exterior.coords)
            px, py = page.xy(ring[:, 0], ring[:, 1])
            layer.line(list(zip(px.tolist(), py.tolist(), strict=True)), fill=_rgb(colour, 0.9), width=width)
        cx, cy = (float(v) for v in page.xy(float(st.x_m[0]) - ox, float(st.y_m[0]) - oy))
        labels.append((cx, cy, number, colour))
    r = page.pt(6.5)
    for cx, cy, number, colour in labels:  # over every outline
        page.draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill="white", outline=colour, width=width + 1)
        page.text((cx, cy), str(number), 7.5, anchor="mm", bold=True, fill="#212121")


def draw_map(plan: MapPlan, *, max_footprints: int, max_stations: int, dpi: int) -> Image.Image:
    """The map of ``plan`` (a plan's :func:`~planner.mapview.map_view`) as an RGB image, ``dpi``
    pixels per inch: :func:`draw_body`, then :func:`finish` with the plan's texts."""
    body = draw_body(plan, max_footprints=max_footprints, max_stations=max_stations, dpi=dpi)
    return finish(body, plan.header, plan.caption)


@dataclass
class MapBody:
    """A map drawn but for its header, caption and legend (:func:`draw_body`): the page (at the
    PNG's size), the plan's name (the title) and the legend's entries."""

    page: _Page | None  # None once finished
    name: str
    entries: list[tuple[str, dict[str, Any]]]


def draw_body(
    plan: MapPlan,
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
    dpi: int = 130,
) -> MapBody:
    """Everything of the map of ``plan`` but the lines that need the plan's summary (its
    ``header`` and ``caption`` are not read): `sfap plan` draws it while the summary is made.

    Drawn for the scale of the page: footprints and stations only when they can be told apart
    (else left out, and the legend says so and where they are), each pass group in its colour
    (heights of a multi-scale block and oblique look directions apart), and the plan's sorties
    (numbered from 1) as outlines with their numbers."""
    frame = map_frame(plan)
    # The map box, supersampled (anti-aliasing: reduced onto the page below); the margins are
    # drawn at the page's own size (the legend supersampled on its own canvas: _legend).
    corner, region = _supersampled(
        frame.left_in * dpi,
        frame.top_in * dpi,
        (frame.left_in + frame.map_w_in) * dpi,
        (frame.top_in + frame.map_h_in) * dpi,
    )
    page = _Page(frame, dpi, _SUPERSAMPLE, region)
    ox, oy = plan.home_xy_m
    st = plan.stations
    n = len(st)
    x0, x1, y0, y1 = frame.limits
    box = (page.left, page.top, page.left + page.map_w, page.top + page.map_h)
    entries: list[tuple[str, dict[str, Any]]] = []
    simplified: list[str] = []  # what the scale leaves out, said under the legend
    styles = pass_styles(plan)
    colour_of_pass = {i: style.colour for style in styles for i in style.pass_indices}

    # grid under everything
    xticks = _nice_ticks(x0, x1)
    yticks = _nice_ticks(y0, y1)
    grid_w = max(1, round(page.pt(0.6)))
    for t in xticks:
        px, _ = page.xy(t, 0.0)
        page.draw.line([(float(px), box[1]), (float(px), box[3])], fill="#eeeeee", width=grid_w)
    for t in yticks:
        _, py = page.xy(0.0, t)
        page.draw.line([(box[0], float(py)), (box[2], float(py))], fill="#eeeeee", width=grid_w)

    if not plan.area_xy.is_empty:
        _fill_polygon(page, plan.area_xy, ox, oy, _AREA_FACE)
        _outline(page, plan.area_xy, ox, oy, _AREA_EDGE, 1.2)
    entries.append(("area to cover", {"kind": "patch", "face": _AREA_FACE, "edge": _AREA_EDGE}))
    if plan.exclusions_xy:
        for zone in plan.exclusions_xy:
            _fill_polygon(page, zone, ox, oy, "#f9e4e4")  # the red at 10 % over white
            _fill_polygon(page, zone, ox, oy, _EXCLUSION, hatch_pt=6.0)
            _outline(page, zone, ox, oy, _EXCLUSION, 1.2)
        entries.append(
            (
                f"exclusion zones and holes ({len(plan.exclusions_xy)})",
                {"kind": "patch", "face": "#f9e4e4", "edge": _EXCLUSION, "hatch": True},
            )
        )

    fp_index, fp_step = _thin(n, max_footprints)
    simple = simplification(plan, frame, fp_step)
    footprints_seen = simple.footprints
    if fp_index.size and footprints_seen:
        layer_draw = ImageDraw.Draw(page.image, "RGBA")  # blends each outline into the page
        width = max(1, round(page.pt(0.35)))
        corners = st.footprint_xy_m[fp_index] - (ox, oy)
        px, py = page.xy(corners[..., 0], corners[..., 1])
        colours: dict[int, _Colour] = {}
        for p, xs, ys in zip(st.pass_index[fp_index].tolist(), px.tolist(), py.tolist(), strict=True):
            colour = colours.get(p)
            if colour is None:
                colour = colours[p] = _rgb(colour_of_pass.get(p, _PASS_COLOURS[PassKind.NADIR]), 0.35)
            ring = list(zip(xs, ys, strict=True))
            layer_draw.line([*ring, ring[0]], fill=colour, width=width)
        entries.append(
            (
                _shown(int(fp_index.size), n, fp_step, "frame footprints"),
                {"kind": "patch", "face": None, "edge": "#607d8b", "lw": 0.6},
            )
        )

    if len(plan.path_xy_m) >= 2:
        path = np.column_stack(page.xy(plan.path_xy_m[:, 0] - ox, plan.path_xy_m[:, 1] - oy))
        width = max(1, round(page.pt(0.8)))
        for dash in _dashed(path, page.pt(0.8 * 4), page.pt(0.8 * 3)):
            page.draw.line(dash, fill="#424242", width=width)
        entries.append(("flight path", {"kind": "line", "colour": "#424242", "lw": 0.8, "dashed": True}))

    order = {PassKind.OBLIQUE: 0, PassKind.CROSSHATCH: 1, PassKind.NADIR: 2}
    for p in sorted((p for p in plan.passes if p.lines), key=lambda p: (order[p.kind], -p.alt_agl_m)):
        width_px = page.pt(float(np.clip(0.35 * p.line_spacing_m * frame.points_per_m, 0.25, 1.6)))
        pass_colour = colour_of_pass[p.index]
        r = width_px / 2
        for ln in p.lines:
            (sx, ex), (sy, ey) = page.xy(
                [ln.start_xy_m[0] - ox, ln.end_xy_m[0] - ox], [ln.start_xy_m[1] - oy, ln.end_xy_m[1] - oy]
            )
            page.draw.line([(sx, sy), (ex, ey)], fill=pass_colour, width=max(1, round(width_px)))
            for cx, cy in ((sx, sy), (ex, ey)):  # round caps: a one-photo segment shows as a dot
                page.draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=pass_colour)
    for style in styles:
        entries.append((style.label, {"kind": "line", "colour": style.colour, "lw": 1.6}))

    st_index, st_step = _thin(n, max_stations)
    steps = np.hypot(np.diff(st.x_m), np.diff(st.y_m)) if n > 1 else np.zeros(0)
    spacing_m = median(steps[steps > 0]) if np.any(steps > 0) else 8.0 / frame.points_per_m
    if st_index.size and simple.stations:
        spacing_pt = spacing_m * frame.points_per_m
        area_pt2 = float(np.clip(0.5 * min(spacing_pt, 8.0) ** 2, 0.3, 8.0))
        r = max(page.pt(math.sqrt(area_pt2)) / 2, 0.75)
        px, py = page.xy(st.x_m[st_index] - ox, st.y_m[st_index] - oy)
        alpha = 0.8 if st_index.size > 2000 else 1.0
        layer_draw = ImageDraw.Draw(page.image, "RGBA")
        fill = _rgb("#212121", alpha)
        for cx, cy in zip(px.tolist(), py.tolist(), strict=True):
            layer_draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=fill)
        entries.append(
            (
                _shown(int(st_index.size), n, st_step, "exposure stations"),
                {"kind": "marker", "marker": "o", "ms": 3, "face": "#212121", "edge": "#212121"},
            )
        )
    simplified.extend(simple.notes)

    if plan.sorties:
        _draw_sorties(page, plan.sorties, ox, oy, colour_of_pass)
        entries.append(
            (
                f"sorties ({len(plan.sorties)}): the strip each flies,\nin its pass's colour; its "
                f"number\nwhere it starts",
                {"kind": "patch", "face": None, "edge": _SORTIE_EDGE, "lw": 1.2},
            )
        )

    hx, hy = page.xy(0.0, 0.0)
    page.marker(float(hx), float(hy), "^", 12, "#ffd600", "#000000", 1.2)
    entries.append(
        ("home (0, 0)", {"kind": "marker", "marker": "^", "ms": 10, "face": "#ffd600", "edge": "#000000"})
    )
    if plan.passes and plan.passes[0].lines:
        first = plan.passes[0].lines[0]
        ex_m, ey_m = first.entry_xy_m[0] - ox, first.entry_xy_m[1] - oy
        dx, dy = first.end_xy_m[0] - first.start_xy_m[0], first.end_xy_m[1] - first.start_xy_m[1]
        norm = math.hypot(dx, dy) or 1.0
        arrow_m = 0.08 * frame.span_m
        ex, ey = page.xy(ex_m, ey_m)
        tx, ty = page.xy(ex_m + arrow_m * dx / norm, ey_m + arrow_m * dy / norm)
        page.arrow((float(ex), float(ey)), (float(tx), float(ty)), "#00c853", 2.2, 10)
        page.marker(float(ex), float(ey), "o", 9, "#00c853", "#000000", 1.0)
        entries.append(
            (
                f"entry; first line heading {first.heading_deg:.0f} deg (true)",
                {"kind": "marker", "marker": "o", "ms": 8, "face": "#00c853", "edge": "#000000"},
            )
        )

    # scale bar (lower right) and north arrow (upper right), inside the map box
    length_m = scale_bar_length_m(x1 - x0)
    unit = (y1 - y0) / 100.0
    right_m = x1 - 6.0 * unit
    left_m = right_m - length_m
    bottom_m = y0 + 2.5 * unit
    bx0, by1 = page.xy(left_m - 2.0 * unit, bottom_m - 1.5 * unit)
    bx1, by0 = page.xy(left_m - 2.0 * unit + length_m + 7.0 * unit, bottom_m - 1.5 * unit + 6.0 * unit)
    page.draw.rectangle(
        (float(bx0), float(by0), float(bx1), float(by1)),
        fill="white",
        outline="#424242",
        width=max(1, round(page.pt(0.8))),
    )
    for k in range(4):
        qx0, qy1 = page.xy(left_m + k * length_m / 4, bottom_m)
        qx1, qy0 = page.xy(left_m + (k + 1) * length_m / 4, bottom_m + 1.2 * unit)
        page.draw.rectangle(
            (float(qx0), float(qy0), float(qx1), float(qy1)),
            fill="#000000" if k % 2 == 0 else "white",
            outline="#000000",
            width=max(1, round(page.pt(0.8))),
        )
    lx0, ly0 = page.xy(left_m, bottom_m + 1.8 * unit)
    lx1, _ = page.xy(right_m, bottom_m + 1.8 * unit)
    page.text((float(lx0), float(ly0)), "0", 8, anchor="md")
    label_text = f"{length_m / 1000:g} km" if length_m >= 1000 else f"{length_m:g} m"
    page.text((float(lx1), float(ly0)), label_text, 9, anchor="md")
    nx = box[0] + 0.95 * page.map_w
    page.arrow((nx, box[1] + 0.16 * page.map_h), (nx, box[1] + 0.04 * page.map_h), "#000000", 2.0, 11)
    page.text((nx, box[1] + 0.16 * page.map_h), "N", 13, anchor="ma", bold=True)

    # what lies outside the map box is cut away (the canvas's edges, up to a pixel wide), then
    # the box is reduced onto the page, and its frame, ticks and labels drawn there
    for edge in (
        (0, 0, page.width, box[1] - 1),
        (0, box[3] + 1, page.width, page.height),
        (0, 0, box[0] - 1, page.height),
        (box[2] + 1, 0, page.width, page.height),
    ):
        if edge[2] >= edge[0] and edge[3] >= edge[1]:
            page.draw.rectangle(edge, fill="white")
    sheet = _Page(frame, dpi, 1)
    sheet.image.paste(page.image.reduce(_SUPERSAMPLE), corner)
    _axes(sheet, xticks, yticks)

    for note in simplified:
        entries.append((note, {"kind": "note"}))
    return MapBody(page=sheet, name=plan.name, entries=entries)


def finish(body: MapBody, header: str, caption: str) -> Image.Image:
    """The map ``body`` with its title, ``header``, ``caption`` and legend: the RGB image. The body
    is finished once: its page is the image returned."""
    page, body.page = body.page, None
    if page is None:
        raise ValueError("this map was finished already")
    _legend(page, body.entries)
    page.text((page.left, page.pt(0.2 * 72)), body.name, 14, bold=True)
    page.text((page.left, page.pt(0.58 * 72)), header, 10)
    page.text((page.left, page.height - page.pt(0.15 * 72)), caption, 8, anchor="ld", fill="#424242")
    return page.image


def png_bytes(
    plan: MapPlan,
    *,
    max_footprints: int = 4000,
    max_stations: int = DEFAULT_MAX_STATIONS,
    dpi: int = 130,
) -> bytes:
    """The map of ``plan`` (a plan's :func:`~planner.mapview.map_view`) as PNG bytes: see
    :func:`planner.mapplot.render_map_png`."""
    if max_footprints < 0 or max_stations < 0:
        raise InputError(
            f"max_footprints = {max_footprints}, max_stations = {max_stations}: both must be 0 or more"
        )
    return encode_png(draw_map(plan, max_footprints=max_footprints, max_stations=max_stations, dpi=dpi))


def encode_png(rgb: Image.Image) -> bytes:
    """A drawn map as PNG bytes."""
    # A map is a few flat colours and their anti-aliased edges: a 256-colour palette keeps
    # them (no dithering) and encodes 3-4x faster and 4x smaller than 24-bit colour. zlib's
    # fastest level: the same pixels as its default (6) in half the time or less (10-20 ms of a
    # small plan's critical path), in a file about 1.5x larger (170 KB for the gully's map).
    image = rgb.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG", compress_level=1)
    return buffer.getvalue()


def write_png(plan: MapPlan, path: str | os.PathLike[str], **options: int) -> Path:
    """map.png of ``plan`` (a plan's :func:`~planner.mapview.map_view`) written atomically to
    ``path``; ``options``: those of :func:`png_bytes`. Returns the path written."""
    return _write(png_bytes(plan, **options), path)


def write_finished(body: MapBody, header: str, caption: str, path: str | os.PathLike[str]) -> Path:
    """map.png of a :func:`draw_body` with the plan's ``header`` and ``caption``, written
    atomically to ``path``. Returns the path written."""
    return _write(encode_png(finish(body, header, caption)), path)


def _write(data: bytes, path: str | os.PathLike[str]) -> Path:
    written = atomic_write_bytes(path, data)
    log.debug("wrote map: %s (%d bytes)", written, len(data))
    return written
