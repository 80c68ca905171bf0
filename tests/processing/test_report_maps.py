"""Gap labels on the report's map never overlap, however close the gaps are."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from processing.report_maps import place_labels


@pytest.mark.parametrize("count", [2, 12, 40])
def test_labels_of_clustered_gaps_do_not_overlap(count: int) -> None:
    figure = Figure(figsize=(7.0, 6.0), dpi=110, layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    ax.set_xlim(0, 1000)
    ax.set_ylim(0, 1000)
    rng = np.random.default_rng(count)
    # Gaps within a few metres of each other on a 1 km map: every label wants the same spot.
    # Half at the centre, half at the map's lower edge, where a label pushed down would leave it.
    anchors = [(500 + rng.normal(0, 3), (500 if k % 2 else 5) + abs(rng.normal(0, 3))) for k in range(count)]
    labels = place_labels(ax, anchors, [str(k + 1) for k in range(count)])
    renderer = figure.canvas.get_renderer()
    figure.canvas.draw()  # the final layout, as savefig renders it
    boxes = [Text.get_window_extent(label, renderer) for label in labels]
    overlapping = [(i, j) for i in range(count) for j in range(i) if boxes[i].overlaps(boxes[j])]
    assert overlapping == []
    # ... and every label inside the map.
    inside = ax.get_window_extent(renderer)
    assert all(
        inside.x0 <= b.x0 and b.x1 <= inside.x1 and inside.y0 <= b.y0 and b.y1 <= inside.y1 for b in boxes
    )
    # Each label still points at its own gap (the anchor is the gap's point).
    for label, anchor in zip(labels, anchors, strict=True):
        assert label.xy == pytest.approx(anchor)
    # The first label at the centre (the largest gap there) keeps its place on its anchor; the
    # one on the map's edge moved inside.
    assert labels[1].get_position() == (0, 0)
    assert labels[0].get_position() != (0, 0)


# ------------------------------------------------------------------ issue 24: the maps read at a glance


@pytest.fixture(scope="module")
def gully_check(gully: tuple[object, Path]) -> object:
    """The check of the gully's plan folder (its own frames, flat ground at take-off)."""
    from processing.check import run_check
    from processing.ground_choice import ground_from_options
    from processing.plan_frames import frames_from_plan

    _, folder = gully
    frames, info = frames_from_plan(folder)
    choice = ground_from_options(frames=frames)
    return run_check(choice.frames, ground=choice.ground, plan=info)


def _north_arrow(ax: object) -> object:
    from matplotlib.text import Annotation

    arrows = [a for a in ax.texts if isinstance(a, Annotation) and a.get_gid() == "north-arrow"]  # type: ignore[attr-defined]
    assert len(arrows) == 1
    return arrows[0]


@pytest.mark.parametrize("which", ["gsd", "base_height"])
def test_a_report_map_states_its_origin_and_has_a_north_arrow_and_a_true_scale_bar(
    gully_check: object, which: str
) -> None:
    """The caption's origin, read back through pyproj in the check's grid, is the area's
    south-west corner (0, 0 of the axes); the arrow points up the grid; the scale bar's length is
    the ground distance its label says (geodesic, between its ends)."""
    import re

    from geographiclib.geodesic import Geodesic
    from matplotlib.patches import Rectangle
    from pyproj import Transformer

    from processing.report_maps import base_height_map, gsd_map

    result = gully_check
    m = (gsd_map if which == "gsd" else base_height_map)(result)  # type: ignore[arg-type]
    figure = m.finish()
    ax = m.ax
    caption = figure._supxlabel.get_text().replace("\n", " ")  # type: ignore[attr-defined]
    found = re.search(
        r"Origin \(0, 0\): the area's south-west corner, ([\d.]+) deg ([NS]), ([\d.]+) deg ([EW])", caption
    )
    assert found is not None, caption
    lat = float(found.group(1)) * (1 if found.group(2) == "N" else -1)
    lon = float(found.group(3)) * (1 if found.group(4) == "E" else -1)
    crs = result.frame.crs  # type: ignore[attr-defined]
    x, y = Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon, lat)
    minx, miny, _, _ = result.area_xy.bounds  # type: ignore[attr-defined]
    assert abs(x - minx) < 1.0 and abs(y - miny) < 1.0  # 5 decimals of a degree: about 1 m
    assert "transverse Mercator" in caption or "EPSG:" in caption
    # One CRS for the check's files, named on every map: the UTM zone of the area's longitude.
    zone = int((lon + 180.0) // 6.0) + 1
    assert (
        f"files (coverage.tif, report.json) are in EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"
        in caption
    )

    arrow = _north_arrow(ax)
    (tx, ty), (sx, sy) = arrow.xy, arrow.xyann  # type: ignore[attr-defined]
    assert tx == pytest.approx(sx) and ty > sy and arrow.get_text() == "N"  # type: ignore[attr-defined]

    quarters = sorted(
        (p for p in ax.patches if isinstance(p, Rectangle) and p.get_zorder() == 10), key=lambda p: p.get_x()
    )
    assert len(quarters) == 4
    left, right = quarters[0].get_x(), quarters[-1].get_x() + quarters[-1].get_width()
    label = next(t.get_text() for t in ax.texts if re.fullmatch(r"[\d.]+ k?m", t.get_text()))
    value, unit = label.split()
    stated = float(value) * (1000.0 if unit == "km" else 1.0)
    ox, oy = m.origin
    back = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
    (lon0, lon1), (lat0, lat1) = back.transform([left + ox, right + ox], [quarters[0].get_y() + oy] * 2)
    assert Geodesic.WGS84.Inverse(lat0, lon0, lat1, lon1)["s12"] == pytest.approx(stated, rel=1e-3)


def test_the_titles_stay_clear_of_the_colour_bar(gully_check: object) -> None:
    """Every title (the figure's, any axes') lies inside the picture and off the colour bar and
    its labels (base_height.png's long title ran under the colour bar)."""
    from processing.report_maps import base_height_map, gsd_map

    for build in (base_height_map, gsd_map):
        m = build(gully_check)  # type: ignore[arg-type]
        figure = m.finish()
        figure.canvas.draw()
        renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
        titles = [figure._suptitle] + [ax.title for ax in figure.axes if ax.title.get_text()]  # type: ignore[attr-defined]
        titles = [t for t in titles if t is not None and t.get_text().strip()]
        assert titles
        bars = [ax for ax in figure.axes if ax is not m.ax]
        assert bars  # both maps have a colour bar
        for title in titles:
            box = title.get_window_extent(renderer)
            assert box.x0 >= 0 and box.x1 <= figure.bbox.width and box.y1 <= figure.bbox.height
            for bar in bars:
                assert not box.overlaps(bar.get_tightbbox(renderer)), title.get_text()
            assert not box.overlaps(m.ax.get_window_extent(renderer))


def test_the_gsd_scale_is_anchored_on_the_planned_gsd_and_the_tolerance(gully_check: object) -> None:
    """A block within a few hundredths of a centimetre of its target reads as one colour: the
    scale spans the planned GSD -/+ 10 % (the check's own warning), white at the target."""
    from matplotlib.colors import to_rgb

    from processing.report_maps import GSD_TOLERANCE, gsd_map

    result = gully_check
    planned = result.plan.planned.summary.gsd_cm  # type: ignore[attr-defined]
    m = gsd_map(result)  # type: ignore[arg-type]
    image = next(i for i in m.ax.images if i.get_zorder() == 2)
    assert image.norm.vmin == pytest.approx(planned * (1 - GSD_TOLERANCE))
    assert image.norm.vmax == pytest.approx(planned * (1 + GSD_TOLERANCE))
    assert to_rgb(image.cmap(image.norm(planned))) == pytest.approx((0.97, 0.97, 0.97), abs=0.04)
    spread = np.nanmax(result.gsd_cm_raster) - np.nanmin(result.gsd_cm_raster)  # type: ignore[attr-defined]
    assert spread < 0.2 * planned * GSD_TOLERANCE  # the premise: a small spread ...
    colours = image.cmap(
        image.norm(np.array([np.nanmin(result.gsd_cm_raster), np.nanmax(result.gsd_cm_raster)]))
    )  # type: ignore[attr-defined]
    assert np.abs(colours[0] - colours[1]).max() < 0.25  # ... stays nearly one colour
    labels = [t.get_text() for t in m.figure.axes[-1].get_yticklabels()]
    assert any("planned" in t for t in labels) and any("+10 %" in t for t in labels)
