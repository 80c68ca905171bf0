"""Ground control layout: every point inside the area and clear of the exclusions, seen by the
asked number of planned frames (counted here with a point-in-quadrilateral test of our own), the
asked numbers of GCPs and check points, apart from each other; asking for more than the area
holds is refused with the figures."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon
from survey_oracles import make_spec
from test_survey import star_polygon, to_lonlat_polygon

import planner.gcp_layout
from planner.errors import InputError
from planner.gcp_layout import GcpOptions, frame_counts, plan_gcps, usable_ground
from planner.plan import SurveyPlan
from planner.spec import load_spec
from planner.survey import plan_polygons, plan_survey

REPO = Path(__file__).resolve().parents[2]


def frames_seeing(plan: SurveyPlan, x: float, y: float) -> int:
    """Footprints (convex quadrilaterals) holding the point: the point is on the same side of
    all four edges."""
    q = plan.stations.footprint_xy_m  # (N, 4, 2)
    a, b = q, np.roll(q, -1, axis=1)
    cross = (b[..., 0] - a[..., 0]) * (y - a[..., 1]) - (b[..., 1] - a[..., 1]) * (x - a[..., 0])
    inside = np.all(cross > 0, axis=1) | np.all(cross < 0, axis=1)
    return int(np.count_nonzero(inside))


@settings(max_examples=15, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    outer=star_polygon(r_min=200.0, r_max=450.0),
    exclusion=star_polygon(centre=(60.0, -40.0), r_min=15.0, r_max=60.0, n_max=6),
    gcps=st.integers(3, 12),
    checks=st.integers(0, 6),
    min_frames=st.integers(1, 9),
    clearance=st.floats(0.0, 20.0),
    margin=st.floats(0.0, 15.0),
)
def test_points_inside_clear_and_seen(
    outer: list[tuple[float, float]],
    exclusion: list[tuple[float, float]],
    gcps: int,
    checks: int,
    min_frames: int,
    clearance: float,
    margin: float,
) -> None:
    keep = Polygon(outer).buffer(-5).contains(Polygon(exclusion))
    spec = make_spec({"gsd_cm": 2.5, "front_overlap_pct": 75, "side_overlap_pct": 65})
    plan = plan_polygons(spec, [to_lonlat_polygon(outer)], [to_lonlat_polygon(exclusion)] if keep else [])
    options = GcpOptions(
        gcp_count=gcps,
        check_count=checks,
        min_frames=min_frames,
        clearance_m=clearance,
        edge_margin_m=margin,
        min_separation_m=30.0,
    )
    layout = plan_gcps(plan, options)
    assert sum(p.role == "gcp" for p in layout.points) == gcps
    assert sum(p.role == "check" for p in layout.points) == checks
    assert sum(p.placement == "corner" for p in layout.points) == min(4, gcps)
    area = plan.area_xy
    outline = plan.frame.geometry_to_xy(to_lonlat_polygon(outer)).exterior
    for p in layout.points:
        point = Point(p.x_m, p.y_m)
        assert area.contains(point)
        assert outline.distance(point) >= margin - 1e-6
        for zone in plan.exclusions_xy:
            assert zone.distance(point) >= clearance - 1e-6
        seen = frames_seeing(plan, p.x_m, p.y_m)
        assert seen >= min_frames
        assert seen == p.frame_count
        # the lon/lat written matches the projected coordinates
        x, y = plan.frame.to_xy(p.lon_deg, p.lat_deg)
        assert math.dist((float(x), float(y)), (p.x_m, p.y_m)) < 0.01
    xy = np.array([(p.x_m, p.y_m) for p in layout.points])
    d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    assert d[np.triu_indices(len(xy), 1)].min() >= 30.0 - 1e-6


def test_frame_counts_match_a_brute_force_count_over_every_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    """The frames that see each point, counted block by block through the index over the points,
    are those a brute-force test of every footprint polygon finds (shapely's contains_xy of each
    point against every frame, no index): on the quarry's six passes (nadir, crosshatch, four obliques),
    for random points over the block, footprint corners and edge midpoints (on an edge: not
    held), with blocks of 997 frames so that many blocks and a partial last one are summed."""
    plan = plan_survey(load_spec(REPO / "missions" / "quarry-block.toml"))
    quads = plan.stations.footprint_xy_m
    assert len(quads) > 10 * 997
    monkeypatch.setattr(planner.gcp_layout, "FOOTPRINT_BLOCK", 997)
    rng = np.random.default_rng(21)
    x0, y0, x1, y1 = plan.area_xy.bounds
    pad = 0.2 * max(x1 - x0, y1 - y0)
    picks = rng.choice(len(quads), 30, replace=False)
    corners = quads[picks].reshape(-1, 2)
    midpoints = ((quads[picks] + np.roll(quads[picks], -1, axis=1)) / 2).reshape(-1, 2)
    xy = np.vstack([rng.uniform((x0 - pad, y0 - pad), (x1 + pad, y1 + pad), (150, 2)), corners, midpoints])
    polygons = np.array([Polygon(q) for q in quads], dtype=object)
    expected = np.array([np.count_nonzero(shapely.contains_xy(polygons, x, y)) for x, y in xy], np.int64)
    got = frame_counts(plan, xy[:, 0].copy(), xy[:, 1].copy())
    assert expected.max() >= 20 and (expected == 0).any()  # the points span unseen to well seen
    np.testing.assert_array_equal(got, expected)


def test_corners_and_interior_are_spread() -> None:
    """On a square the four corner GCPs sit near the four corners and the interior ones inside."""
    square = [(0.0, 0.0), (600.0, 0.0), (600.0, 600.0), (0.0, 600.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.5}), [to_lonlat_polygon(square)], [])
    layout = plan_gcps(plan, GcpOptions(gcp_count=9, check_count=4, min_frames=3, edge_margin_m=10.0))
    corners_xy = [plan.frame.to_xy(*to_lonlat_polygon(square).exterior.coords[k]) for k in range(4)]
    corner_points = [p for p in layout.points if p.placement == "corner"]
    for cx, cy in corners_xy:
        assert min(math.dist((float(cx), float(cy)), (p.x_m, p.y_m)) for p in corner_points) < 60.0
    interior = [p for p in layout.points if p.placement == "interior"]
    assert interior and all(plan.area_xy.boundary.distance(Point(p.x_m, p.y_m)) > 60.0 for p in interior)


def test_more_points_than_the_area_holds_is_refused() -> None:
    """Issue 24: an impossible request is bad input (InputError: exit 2) naming the options and
    one figure, the number that fits; asking for that many (split as it says) succeeds."""
    small = [(0.0, 0.0), (120.0, 0.0), (120.0, 100.0), (0.0, 100.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.0}), [to_lonlat_polygon(small)], [])
    with pytest.raises(InputError) as info:
        plan_gcps(plan, GcpOptions(gcp_count=20, check_count=5, min_frames=1, min_separation_m=30.0))
    text = str(info.value)
    assert text.startswith("--gcp 20 --check 5 asks for 25 points 30 m apart"), text
    found = re.search(
        r"only (\d+) fit; ask for (\d+) points or fewer \(e\.g\. --gcp (\d+) --check (\d+)\)", text
    )
    assert found is not None, text
    fits, again, gcp, check = (int(g) for g in found.groups())
    assert fits == again == gcp + check and gcp >= 3
    layout = plan_gcps(
        plan, GcpOptions(gcp_count=gcp, check_count=check, min_frames=1, min_separation_m=30.0)
    )
    assert len(layout.points) == fits
    assert "holds about" not in text  # no second, contradicting figure
    with pytest.raises(InputError, match="at least 3 GCPs"):
        GcpOptions(gcp_count=2)


def test_a_margin_that_leaves_no_ground_names_the_option_and_the_margin_that_fits() -> None:
    """A 120 m x 100 m rectangle: ground is left only with a margin below half its short side
    (50 m, less the 1 % + 1 cm the buffers are padded by: 49.49 m)."""
    rect = [(0.0, 0.0), (120.0, 0.0), (120.0, 100.0), (0.0, 100.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.0}), [to_lonlat_polygon(rect)], [])
    with pytest.raises(InputError) as info:
        plan_gcps(plan, GcpOptions(gcp_count=3, check_count=0, min_frames=1, edge_margin_m=60.0))
    text = str(info.value)
    assert "edge_margin_m" not in text and "clearance_m" not in text
    found = re.search(
        r"^--edge-margin-m 60 .*leave no ground.*ask for --edge-margin-m ([\d.]+) or less", text
    )
    assert found is not None, text
    fits = float(found.group(1))
    assert fits == pytest.approx((50.0 - 0.01) / 1.01, abs=0.11)
    assert usable_ground(plan, GcpOptions(edge_margin_m=fits)).area > 0
    assert usable_ground(plan, GcpOptions(edge_margin_m=fits + 0.2)).is_empty


def test_too_many_frames_asked_names_the_most_a_point_gets() -> None:
    square = [(0.0, 0.0), (300.0, 0.0), (300.0, 300.0), (0.0, 300.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.5}), [to_lonlat_polygon(square)], [])
    with pytest.raises(InputError) as info:
        plan_gcps(plan, GcpOptions(gcp_count=3, check_count=0, min_frames=1000))
    found = re.search(
        r"^--min-frames 1000: .* the most any point gets is (\d+): ask for --min-frames \1", str(info.value)
    )
    assert found is not None, str(info.value)
    most = int(found.group(1))
    layout = plan_gcps(plan, GcpOptions(gcp_count=3, check_count=0, min_frames=most, min_separation_m=1.0))
    assert min(frames_seeing(plan, p.x_m, p.y_m) for p in layout.points) == most


@pytest.mark.parametrize(
    ("field", "value", "option"),
    [
        ("check_count", -1, "--check -1"),
        ("min_frames", 0, "--min-frames 0"),
        ("clearance_m", -1.0, "--clearance-m -1"),
        ("edge_margin_m", math.nan, "--edge-margin-m nan"),
        ("min_separation_m", math.inf, "--min-separation-m inf"),
    ],
)
def test_bad_options_are_named_as_the_command_spells_them(field: str, value: float, option: str) -> None:
    with pytest.raises(InputError) as info:
        GcpOptions(**{field: value})  # type: ignore[arg-type]
    assert str(info.value).startswith(option), str(info.value)


def test_expected_accuracy_follows_the_gsd() -> None:
    square = [(0.0, 0.0), (300.0, 0.0), (300.0, 300.0), (0.0, 300.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.0}), [to_lonlat_polygon(square)], [])
    acc = plan_gcps(plan, GcpOptions(gcp_count=5, check_count=2, min_frames=3)).expected_accuracy()
    assert acc["horizontal_rmse_m"] == pytest.approx([0.02, 0.04], rel=1e-3)
    assert acc["vertical_rmse_m"] == pytest.approx([0.03, 0.06], rel=1e-3)
    assert "rule of thumb" in str(acc["basis"])
