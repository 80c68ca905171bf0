"""map.png's drawing (planner.maprender), pixel for pixel: the area fill against Pillow's own
blended paste through an "L" mask (the fill copies the colour through a "1" mask, which must
give the same pixels because a polygon mask is only ever 0 or 255, checked too); the legend, on
its own supersampled canvas of the height it needs, against the same drawn on a canvas down to
the page's bottom."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image, ImageDraw
from shapely.geometry import Polygon

from planner.maprender import _fill_polygon


def _page(width: int, height: int) -> SimpleNamespace:
    """The part of maprender's page the fill uses: an RGB image, its size, metres to pixels."""
    image = Image.new("RGB", (width, height), "white")
    ImageDraw.Draw(image).line([(0, 0), (width, height)], fill="#123456", width=5)  # not blank

    def points(xy_m: np.ndarray) -> list[tuple[float, float]]:
        return [(float(x) * 3.7 + 11.3, float(y) * 3.7 + 7.9) for x, y in xy_m]

    return SimpleNamespace(image=image, width=width, height=height, points=points)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(3, 9),
    radius=st.floats(5.0, 60.0),
    hole=st.booleans(),
    seed=st.integers(0, 2**16),
    colour=st.sampled_from(["#e3f1d4", "#f9e4e4", "#000000", "#fffffe"]),
)
def test_area_fill_is_the_blended_paste_through_an_l_mask(
    n: int, radius: float, hole: bool, seed: int, colour: str
) -> None:
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * math.pi, n))
    radii = radius * rng.uniform(0.5, 1.0, n)
    shell = np.column_stack([50 + radii * np.cos(angles), 40 + radii * np.sin(angles)])
    holes = [50 + np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.5], [-2.5, 2.0]])] if hole else []
    polygon = Polygon(shell, [np.column_stack([h[:, 0], h[:, 1] - 10]) for h in holes])
    page = _page(420, 360)
    expected = page.image.copy()
    _fill_polygon(page, polygon, 0.0, 0.0, colour)  # type: ignore[arg-type]

    # Oracle: the same rings drawn on an "L" mask over their bounding box (the pixel grid the
    # fill draws on: Pillow's rasterisation of float corners is not exactly shift-invariant),
    # pasted by Pillow's blending of every pixel.
    rings = [page.points(np.asarray(r.coords)) for r in (polygon.exterior, *polygon.interiors)]
    left = max(0, math.floor(min(x for x, _ in rings[0])))
    top = max(0, math.floor(min(y for _, y in rings[0])))
    right = min(page.width, math.ceil(max(x for x, _ in rings[0])) + 1)
    bottom = min(page.height, math.ceil(max(y for _, y in rings[0])) + 1)
    mask = Image.new("L", (right - left, bottom - top), 0)
    draw = ImageDraw.Draw(mask)
    for k, ring in enumerate(rings):
        draw.polygon([(x - left, y - top) for x, y in ring], fill=255 if k == 0 else 0)
    expected.paste(colour, (left, top, right, bottom), mask=mask)
    assert set(mask.tobytes()) <= {0, 255}
    assert page.image.tobytes() == expected.tobytes()


@pytest.mark.parametrize("spec", ["quarry-block-sorties.toml", "field-concave.toml"])
def test_the_legends_canvas_holds_all_of_it(spec: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The legend (the sorties' block: twelve entries, notes wrapped over lines) drawn on a canvas
    of the height it computes is the same picture as drawn on one reaching the page's bottom:
    nothing of it is cut."""
    import planner.maprender as maprender
    from planner.mapview import map_view
    from planner.plan_run import plan_spec

    run = plan_spec(Path(__file__).resolve().parents[2] / "missions" / spec)
    view = map_view(run.plan, [s.plan for s in run.sorties])
    fitted = maprender.png_bytes(view)
    monkeypatch.setattr(maprender, "_legend_height_pt", lambda *args: 1e6)
    assert maprender.png_bytes(view) == fitted
