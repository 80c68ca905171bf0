"""map.png: its header and its legend count the same lines, and the planner's summary agrees
(issue 13). The planner counts rows from its own line layout; the map groups the camera-on
segments by their offset across the pass: two constructions that must meet."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.maplayout import pass_line_count
from planner.mapplot import render_map_figure
from planner.spec import load_spec
from planner.stats import median
from planner.survey import plan_survey

MISSIONS = sorted((Path(__file__).resolve().parents[2] / "missions").glob("*.toml"))


@pytest.mark.parametrize("mission", MISSIONS, ids=[m.stem for m in MISSIONS])
def test_header_and_legend_agree_on_the_number_of_lines(mission: Path) -> None:
    plan = plan_survey(load_spec(mission))
    fig = render_map_figure(plan)
    header = " ".join(t.get_text() for t in fig.texts)
    match = re.search(r"([\d,]+) lines?(?: in ([\d,]+) segments)?, \d+ pass", header)
    assert match is not None, header
    header_lines = int(match.group(1).replace(",", ""))
    legend = fig.axes[0].get_legend()
    assert legend is not None
    legend_lines = 0
    for text in legend.get_texts():
        found = re.match(r"camera on, \w+ \(([\d,]+) lines?", text.get_text())
        if found:
            legend_lines += int(found.group(1).replace(",", ""))
    assert header_lines == legend_lines == plan.summary.line_count
    segments = sum(len(p.lines) for p in plan.passes)
    assert (match.group(2) is not None) == (segments != header_lines)
    if match.group(2) is not None:
        assert int(match.group(2).replace(",", "")) == segments


def test_pass_line_count_groups_segments_of_one_row() -> None:
    plan = plan_survey(load_spec(MISSIONS[0]))
    nadir = plan.passes[0]
    # a row split into two pieces (a hole) is still one line; a shifted copy is another line
    first = nadir.lines[0]
    mid = ((first.start_xy_m[0] + first.end_xy_m[0]) / 2, (first.start_xy_m[1] + first.end_xy_m[1]) / 2)
    halves = (
        type(first)(**{**first.__dict__, "end_xy_m": mid}),
        type(first)(**{**first.__dict__, "start_xy_m": mid}),
    )
    split = type(nadir)(**{**nadir.__dict__, "lines": halves})
    assert pass_line_count(split) == 1
    dx, dy = first.end_xy_m[0] - first.start_xy_m[0], first.end_xy_m[1] - first.start_xy_m[1]
    norm = (dx * dx + dy * dy) ** 0.5
    shift = (-dy / norm * 0.05, dx / norm * 0.05)  # 5 cm across the line
    moved = type(first)(
        **{
            **first.__dict__,
            "start_xy_m": (first.start_xy_m[0] + shift[0], first.start_xy_m[1] + shift[1]),
            "end_xy_m": (first.end_xy_m[0] + shift[0], first.end_xy_m[1] + shift[1]),
        }
    )
    assert pass_line_count(type(nadir)(**{**nadir.__dict__, "lines": (first, moved)})) == 2


def _pixel(frame: object, x_m: float, y_m: float, dpi: int) -> tuple[int, int]:
    x0, x1, y0, y1 = frame.limits  # type: ignore[attr-defined]
    col = (frame.left_in + (x_m - x0) / (x1 - x0) * frame.map_w_in) * dpi  # type: ignore[attr-defined]
    row = (frame.top_in + (y1 - y_m) / (y1 - y0) * frame.map_h_in) * dpi  # type: ignore[attr-defined]
    return round(row), round(col)


def test_map_png_draws_every_camera_on_segment_where_it_lies(tmp_path: Path) -> None:
    """Every camera-on segment is inked in its pass colour along its length, and a one-photo
    segment (start = end) shows as its station's dot, at the place the page layout puts it."""
    import numpy as np
    from PIL import Image

    from planner.maplayout import PASS_COLOURS, map_frame
    from planner.mapplot import render_map_png

    plan = plan_survey(load_spec(MISSIONS[[m.stem for m in MISSIONS].index("field-concave")]))
    points = [ln for p in plan.passes for ln in p.lines]
    # issue 13: no output holds a zero-length line (a one-photo run is stretched by the planner)
    assert all(ln.length_m > 0 for ln in points)
    png = np.asarray(Image.open(render_map_png(plan, tmp_path / "map.png")).convert("RGB")).astype(int)
    frame = map_frame(plan)
    ox, oy = plan.home_xy_m
    blue = np.array([int(PASS_COLOURS[plan.passes[0].kind][i : i + 2], 16) for i in (1, 3, 5)])
    for ln in points:
        # a segment: its own colour somewhere along it (station dots are drawn over it);
        # a one-photo segment (start = end): its station's dot
        inked = False
        for t in (0.1, 0.3, 0.5, 0.7, 0.9):
            x = ln.start_xy_m[0] + t * (ln.end_xy_m[0] - ln.start_xy_m[0]) - ox
            y = ln.start_xy_m[1] + t * (ln.end_xy_m[1] - ln.start_xy_m[1]) - oy
            row, col = _pixel(frame, x, y, 130)
            patch = png[row - 1 : row + 2, col - 1 : col + 2].reshape(-1, 3)
            if ln.length_m > 0:  # (the first line lies under the green entry arrow)
                inked |= bool((np.abs(patch - blue).max(axis=1) < 60).any())
                inked |= bool((np.abs(patch - (0, 200, 83)).max(axis=1) < 30).any())
            else:
                inked |= bool((patch.max(axis=1) < 90).any())
        assert inked, ln
    # and a place inside the area, away from lines, is the area's green
    area_point = plan.area_xy.representative_point()
    row, col = _pixel(frame, area_point.x - ox, area_point.y - oy, 130)
    around = png[row - 30 : row + 30, col - 30 : col + 30].reshape(-1, 3)
    assert (np.abs(around - (0xE3, 0xF1, 0xD4)).max(axis=1) <= 3).sum() > 100  # 256-colour palette


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64), st.just(float("nan"))),
        min_size=1,
        max_size=40,
    )
)
def test_median_is_numpy_median(values: list[float]) -> None:
    """The map's median (without numpy.ma) is numpy's, bit for bit: odd and even counts, ties,
    huge values whose sum overflows, NaN."""
    expected = float(np.median(np.array(values)))
    got = median(np.array(values))
    assert (np.isnan(got) and np.isnan(expected)) or got == expected
    assert np.signbit(got) == np.signbit(expected) or np.isnan(expected)


def test_median_of_nothing_is_refused() -> None:
    with pytest.raises(ValueError, match="no values"):
        median(np.zeros(0))


# ------------------------------------------------------------------ issue 24: a map read at its scale


def _plan(name: str) -> object:
    return plan_survey(load_spec(MISSIONS[0].parent / f"{name}.toml"))


def test_passes_of_other_heights_and_looks_get_their_own_colours() -> None:
    """The multi-scale block's two nadir heights, and the quarry's four oblique looks, are told
    apart by colour and named in the legend; the groups still count every line once."""
    from planner.maplayout import pass_styles

    multiscale = _plan("field-multiscale")
    styles = pass_styles(multiscale)  # type: ignore[arg-type]
    heights = sorted({round(p.alt_agl_m) for p in multiscale.passes if p.lines})  # type: ignore[attr-defined]
    assert len(heights) == 2
    assert len(styles) == 2 and len({s.colour for s in styles}) == 2
    for style, height in zip(sorted(styles, key=lambda s: s.label), sorted(heights, key=str), strict=True):
        assert f"at {height:g} m" in style.label or any(f"at {h:g} m" in style.label for h in heights)
    quarry = _plan("quarry-block")
    styles = pass_styles(quarry)  # type: ignore[arg-type]
    obliques = [s for s in styles if "oblique" in s.label]
    assert len(obliques) == 4 and len({s.colour for s in obliques}) == 4
    assert len({s.colour for s in styles}) == len(styles)
    for plan in (multiscale, quarry):
        counted = 0
        for style in pass_styles(plan):  # type: ignore[arg-type]
            found = re.search(r"\(([\d,]+) lines?", style.label)
            assert found is not None, style.label
            counted += int(found.group(1).replace(",", ""))
        assert counted == plan.summary.line_count  # type: ignore[attr-defined]
        drawn = sorted(i for s in pass_styles(plan) for i in s.pass_indices)  # type: ignore[arg-type]
        assert drawn == sorted(p.index for p in plan.passes if p.lines)  # type: ignore[attr-defined]


def test_stations_and_footprints_are_drawn_only_where_they_can_be_told_apart() -> None:
    """On the page each map gets: the gully's 628 stations are apart and drawn; the quarry's
    11,788 over six crossing passes are a mat, left out, and the legend says so and where they
    are. The oracle is the page's own scale: the stations' spacing in points and their count per
    square inch of the area, computed here from the stations and the page size."""
    from planner.maplayout import MAX_STATIONS_PER_IN2, MIN_VISIBLE_SPACING_PT, map_frame, simplification

    for name, drawn in (("bardenas-gully", True), ("quarry-block", False)):
        plan = _plan(name)
        frame = map_frame(plan)  # type: ignore[arg-type]
        st = plan.stations  # type: ignore[attr-defined]
        steps = np.hypot(np.diff(st.x_m), np.diff(st.y_m))
        spacing_pt = median(steps[steps > 0]) * frame.points_per_m
        per_in2 = len(st) / (plan.area_xy.area * (frame.points_per_m / 72) ** 2)  # type: ignore[attr-defined]
        visible = spacing_pt >= MIN_VISIBLE_SPACING_PT and per_in2 <= MAX_STATIONS_PER_IN2
        assert visible is drawn, (name, spacing_pt, per_in2)
        simple = simplification(plan, frame)  # type: ignore[arg-type]
        assert simple.stations is drawn and simple.footprints is drawn
        if not drawn:
            assert any("exposure stations not drawn" in n and "stations.geojson" in n for n in simple.notes)
            assert any("footprints not drawn" in n for n in simple.notes)
        else:
            assert simple.notes == ()


def test_the_quarry_map_draws_its_sorties(tmp_path: Path) -> None:
    """Each sortie's number sits in a white disc at its first station, ringed in its pass's
    colour: read back from the PNG at the place the page layout puts that station."""
    import matplotlib.image as mpimg

    from planner.maplayout import map_frame, pass_styles
    from planner.mapplot import render_map_png
    from planner.sorties import split_sorties

    plan = _plan("quarry-block-sorties")
    sorties = split_sorties(plan)  # type: ignore[arg-type]
    assert len(sorties) > 10
    dpi = 100
    render_map_png(plan, tmp_path / "map.png", dpi=dpi, sorties=[s.plan for s in sorties])  # type: ignore[arg-type]
    rgb = mpimg.imread(tmp_path / "map.png")[..., :3]
    frame = map_frame(plan)  # type: ignore[arg-type]
    ox, oy = plan.home_xy_m  # type: ignore[attr-defined]
    colour_of = {i: s.colour for s in pass_styles(plan) for i in s.pass_indices}  # type: ignore[arg-type]
    x0, x1, y0, y1 = frame.limits
    radius_px = 6.5 / 72 * dpi
    found = 0
    for sortie in sorties:
        st = sortie.plan.stations
        x_m, y_m = float(st.x_m[0]) - ox, float(st.y_m[0]) - oy
        col = (frame.left_in + (x_m - x0) / (x1 - x0) * frame.map_w_in) * dpi
        row = (frame.top_in + (y1 - y_m) / (y1 - y0) * frame.map_h_in) * dpi
        ring = np.array([int(colour_of[int(st.pass_index[0])][i : i + 2], 16) / 255 for i in (1, 3, 5)])
        angles = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        on_ring = [
            rgb[round(row + radius_px * np.sin(a)), round(col + radius_px * np.cos(a))] for a in angles
        ]
        near = sum(np.abs(px - ring).max() < 0.2 for px in on_ring)
        inside = rgb[round(row - 0.55 * radius_px), round(col)]
        found += near >= 6 and inside.min() > 0.85  # its ring in the pass's colour, its white face
    # every sortie's disc, but where two sorties start side by side the later covers the earlier
    assert found >= 0.8 * len(sorties), (found, len(sorties))
