"""Overlapping pairs, base-height ratios, scale outliers and the good-pair share (processing.stereo)
on synthetic blocks whose overlaps and bases are set, so known."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon
from test_footprints import CAMERA, FRAME, ORIGIN_X_M, ORIGIN_Y_M, make_frames

from planner.camera import Orientation
from processing.coverage import Grid, area_mask
from processing.footprints import Footprints, project_footprints
from processing.frames import AltitudeReference, Frames
from processing.ground import FlatGround
from processing.stereo import Pairs, good_pair_share_pct, gsd_raster, overlapping_pairs, scale_outliers

GROUND = FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME)
HEIGHT_M = 100.0
SPEED_M_S = 8.0
START_S = 1_700_000_000.0


def lawnmower(
    forward_pct: float,
    side_pct: float,
    *,
    lines: int = 6,
    stations: int = 15,
    turn_frames: bool = True,
    alt_m: np.ndarray | None = None,
    exposure_s: float | None = 1 / 500,
) -> tuple[Frames, np.ndarray]:
    """A nadir lawnmower over flat ground at HEIGHT_M, landscape, lines north and south, a frame in
    every turn (outside the block) when ``turn_frames``. Frames are in capture order, one every
    base / SPEED_M_S seconds. Returns the frames and which of them are survey stations."""
    fp = CAMERA.footprint(HEIGHT_M, Orientation.LANDSCAPE)
    spacing = fp.across_m * (1 - side_pct / 100)
    base = fp.along_m * (1 - forward_pct / 100)
    xs: list[float] = []
    ys: list[float] = []
    yaws: list[float] = []
    station: list[bool] = []
    for line in range(lines):
        north = line % 2 == 0
        for k in range(stations):
            xs.append(ORIGIN_X_M + line * spacing)
            ys.append(ORIGIN_Y_M + (k if north else stations - 1 - k) * base)
            yaws.append(0.0 if north else 180.0)
            station.append(True)
        if turn_frames and line < lines - 1:
            xs.append(ORIGIN_X_M + (line + 0.5) * spacing)
            ys.append(ORIGIN_Y_M + ((stations - 1) * base + 30 if north else -30))
            yaws.append(90.0)
            station.append(False)
    x, y = np.array(xs), np.array(ys)
    frames = make_frames(
        x, y, HEIGHT_M if alt_m is None else alt_m, np.array(yaws), reference=AltitudeReference.REL_HOME
    )
    steps = np.hypot(np.diff(x), np.diff(y))
    times = START_S + np.concatenate([[0.0], np.cumsum(steps / SPEED_M_S)])
    exposure = None if exposure_s is None else np.full(len(x), exposure_s)
    return dataclasses.replace(frames, time_utc_s=times, exposure_s=exposure), np.array(station)


def project(frames: Frames) -> Footprints:
    return project_footprints(frames, FRAME, GROUND)


def test_nadir_pairs_have_the_textbook_base_height_ratio() -> None:
    """Nadir pair: B/H = (1 - endlap) x sensor length along track / f; angle = 2 atan(B / 2H)."""
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    base_forward = (1 - 0.80) * CAMERA.sensor_height_mm / CAMERA.focal_length_mm
    base_side = (1 - 0.70) * CAMERA.sensor_width_mm / CAMERA.focal_length_mm
    consecutive = (pairs.j == pairs.i + 1) & (pairs.i // 15 == pairs.j // 15)
    np.testing.assert_allclose(pairs.base_height_ratio[consecutive], base_forward, rtol=1e-6)
    np.testing.assert_allclose(pairs.height_m, HEIGHT_M, rtol=1e-9)
    expected_angle = math.degrees(2 * math.atan(base_forward / 2))
    np.testing.assert_allclose(pairs.intersection_angle_deg[consecutive], expected_angle, rtol=1e-6)
    np.testing.assert_allclose(pairs.overlap_i_pct[consecutive], 80.0, atol=0.01)
    # Stations abreast on neighbouring lines (same row of the block).
    row = np.where((pairs.i // 15) % 2 == 0, pairs.i % 15, 14 - pairs.i % 15)
    row_j = np.where((pairs.j // 15) % 2 == 0, pairs.j % 15, 14 - pairs.j % 15)
    abreast = (pairs.j // 15 == pairs.i // 15 + 1) & (row == row_j)
    assert abreast.sum() == 5 * 15
    np.testing.assert_allclose(pairs.base_height_ratio[abreast], base_side, rtol=1e-6)
    assert pairs.scale_ratio == pytest.approx(1.0)


def test_a_frame_flown_higher_is_a_scale_outlier() -> None:
    alt = np.full(90, HEIGHT_M)
    alt[37] = HEIGHT_M * 1.2  # 20 % coarser GSD
    alt[52] = HEIGHT_M * 1.05  # within 10 %
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False, alt_m=alt)
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    np.testing.assert_array_equal(scale_outliers(fp, pairs), [37])
    assert pairs.scale_ratio.max() == pytest.approx(1.2, rel=1e-9)


def test_good_pair_share_is_the_pairs_intersection_over_the_area() -> None:
    fp_size = CAMERA.footprint(HEIGHT_M, Orientation.LANDSCAPE)
    for base_m, in_range in ((fp_size.along_m * 0.2, True), (fp_size.along_m * 0.04, False)):
        frames = make_frames(
            np.full(2, ORIGIN_X_M),
            ORIGIN_Y_M + np.array([0.0, base_m]),
            HEIGHT_M,
            reference=AltitudeReference.REL_HOME,
        )
        fp = project(frames)
        pairs = overlapping_pairs(fp, GROUND, FRAME)
        union = shapely.union_all(fp.polygons())
        grid = Grid.from_bounds(union.buffer(10).bounds, 0.5)
        share = good_pair_share_pct(pairs, grid, area_mask(union, grid))
        if in_range:
            truth = 100 * Polygon(pairs.intersection[0]).area / union.area
            assert share == pytest.approx(truth, abs=100 * union.length * 0.5 / union.area)
        else:
            assert share == 0.0


def test_gsd_raster_keeps_the_finest_gsd() -> None:
    frames = make_frames(
        np.array([ORIGIN_X_M, ORIGIN_X_M + 60]),
        np.array([ORIGIN_Y_M] * 2),
        np.array([100.0, 150.0]),
        reference=AltitudeReference.REL_HOME,
    )
    fp = project(frames)
    grid = Grid.from_bounds((ORIGIN_X_M - 200, ORIGIN_Y_M - 100, ORIGIN_X_M + 200, ORIGIN_Y_M + 100), 1.0)
    gsd = gsd_raster(fp, grid)
    x, y = grid.cell_centres()

    def at(px: float, py: float) -> float:
        return float(gsd[np.argmin(np.abs(y - py)), np.argmin(np.abs(x - px))])

    assert at(ORIGIN_X_M + 30, ORIGIN_Y_M) == pytest.approx(CAMERA.gsd_cm(100.0))  # both see it
    assert at(ORIGIN_X_M + 150, ORIGIN_Y_M) == pytest.approx(CAMERA.gsd_cm(150.0))  # only the higher
    assert math.isnan(at(ORIGIN_X_M - 190, ORIGIN_Y_M + 90))


def test_pair_overlaps_and_centres_equal_shapely_for_tilted_frames() -> None:
    """The numpy clipping of pairs against GEOS, on frames of random heading, tilt and roll."""
    rng = np.random.default_rng(11)
    n = 60
    frames = make_frames(
        ORIGIN_X_M + rng.uniform(0, 300, n),
        ORIGIN_Y_M + rng.uniform(0, 300, n),
        rng.uniform(60, 140, n),
        rng.uniform(0, 360, n),
        rng.uniform(0, 35, n),
        rng.uniform(-10, 10, n),
        reference=AltitudeReference.REL_HOME,
    )
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    polys = fp.polygons()
    inter = shapely.intersection(polys[pairs.i], polys[pairs.j])
    np.testing.assert_allclose(
        pairs.overlap_i_pct, 100 * shapely.area(inter) / fp.area_m2[pairs.i], atol=1e-6
    )
    np.testing.assert_allclose(
        pairs.overlap_j_pct, 100 * shapely.area(inter) / fp.area_m2[pairs.j], atol=1e-6
    )
    np.testing.assert_allclose(
        pairs.ground_xyz_m[:, :2], shapely.get_coordinates(shapely.centroid(inter)), atol=1e-6
    )
    # Every overlapping pair is found, and no other.
    truth = {(a, b) for a in range(n) for b in range(a + 1, n) if polys[a].intersection(polys[b]).area > 0}
    found = set(zip(pairs.i.tolist(), pairs.j.tolist(), strict=True))
    small = {
        (a, b)
        for a, b in truth - found
        if polys[a].intersection(polys[b]).area < 1e-3 * min(polys[a].area, polys[b].area)
    }
    assert found <= truth and truth - found == small


# --- B/H of the pairs that matter, blur along the motion -------------------------------------------


# --- thresholds at their boundaries (exactly at, just below, just above) ---

EPS = 1e-6


@pytest.mark.parametrize(("ratio", "flagged"), [(1.25 - EPS, False), (1.25, False), (1.25 + EPS, True)])
def test_scale_difference(ratio: float, flagged: bool) -> None:
    class Fp:
        gsd_cm = np.array([1.0, ratio, 1.0])

    pairs = Pairs(
        i=np.array([0, 0]),
        j=np.array([1, 2]),
        base_m=np.zeros(2),
        height_m=np.ones(2),
        base_height_ratio=np.zeros(2),
        intersection_angle_deg=np.zeros(2),
        overlap_i_pct=np.zeros(2),
        overlap_j_pct=np.zeros(2),
        scale_ratio=np.ones(2),
        ground_xyz_m=np.zeros((2, 3)),
        intersection=np.zeros((2, 8, 2)),
    )
    outliers = scale_outliers(Fp(), pairs, 0.25)  # type: ignore[arg-type]
    assert (1 in outliers) is flagged
