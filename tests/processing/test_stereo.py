"""Block geometry on synthetic blocks whose overlaps, bases and speeds are set, so known."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon, box
from test_footprints import CAMERA, FRAME, ORIGIN_X_M, ORIGIN_Y_M, make_frames

from planner.camera import Orientation
from processing.coverage import Grid, area_mask
from processing.footprints import Footprints, project_footprints
from processing.frames import AltitudeReference, Frames
from processing.ground import FlatGround
from processing.stereo import (
    analyse_block,
    flight_lines,
    forward_overlaps_pct,
    good_pair_share_pct,
    gsd_raster,
    motion_blur,
    overlapping_pairs,
    scale_outliers,
    side_overlaps_pct,
)

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


@pytest.mark.parametrize(("forward_pct", "side_pct"), [(80.0, 70.0), (60.0, 30.0), (75.0, 65.0)])
def test_measured_overlaps_equal_the_set_ones(forward_pct: float, side_pct: float) -> None:
    frames, station = lawnmower(forward_pct, side_pct)
    fp = project(frames)
    lines = flight_lines(frames, fp)
    # Six survey lines, each turn frame a line of its own: the turns are breaks, not lines' frames.
    assert len(np.unique(lines[station])) == 6
    assert len(np.unique(lines)) == 6 + 5
    assert not np.isin(lines[~station], lines[station]).any()
    forward = forward_overlaps_pct(frames, fp, lines)
    side = side_overlaps_pct(frames, fp, lines)
    # Flat ground, nadir: the set overlaps exactly, up to the lon/lat round trip of positions.
    tolerance = 0.01
    assert forward.size == 6 * 14
    np.testing.assert_allclose(forward, forward_pct, atol=tolerance)
    # Inner lines have two neighbours, the outer two one each.
    assert side.size == 15 * (4 * 2 + 2)
    np.testing.assert_allclose(side, side_pct, atol=tolerance)


def test_plan_line_index_is_used_as_given() -> None:
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    planned = np.repeat(np.arange(6), 15).astype(np.int32)
    with_plan = dataclasses.replace(frames, line_index=planned, time_utc_s=None)
    fp = project(with_plan)
    np.testing.assert_array_equal(flight_lines(with_plan, fp), planned)
    np.testing.assert_allclose(side_overlaps_pct(with_plan, fp, flight_lines(with_plan, fp)), 70.0, atol=0.01)


def test_a_jump_in_a_line_breaks_it() -> None:
    y = ORIGIN_Y_M + np.concatenate([np.arange(10) * 20.0, 400 + np.arange(10) * 20.0])
    frames = make_frames(np.full(20, ORIGIN_X_M), y, HEIGHT_M, reference=AltitudeReference.REL_HOME)
    lines = flight_lines(frames, project(frames))
    np.testing.assert_array_equal(lines, np.repeat([0, 1], 10))


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


def test_a_nadir_block_warns_of_doming_and_obliques_lift_it() -> None:
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    area = box(ORIGIN_X_M, ORIGIN_Y_M, ORIGIN_X_M + 200, ORIGIN_Y_M + 200)
    grid = Grid.from_bounds(area.bounds, 1.0)
    nadir = analyse_block(frames, project(frames), GROUND, FRAME, grid=grid, area_mask=area_mask(area, grid))
    assert nadir.doming_risk and nadir.convergent_share_pct == 0.0
    pitch = frames.pitch_deg.copy()
    pitch[::10] = 20.0  # 9 of 90 frames looking 20 deg forward
    oblique = dataclasses.replace(frames, pitch_deg=pitch)
    result = analyse_block(oblique, project(oblique), GROUND, FRAME)
    assert not result.doming_risk
    assert result.convergent_share_pct == pytest.approx(100.0 * 9 / 90)
    summary = nadir.summary()
    json.dumps(summary)  # the report's JSON takes it as is
    assert summary["forward_overlap_pct"]["median"] == pytest.approx(80.0, abs=0.01)
    assert summary["side_overlap_pct"]["median"] == pytest.approx(70.0, abs=0.01)
    assert summary["good_base_height_area_pct"] == pytest.approx(100.0)
    assert summary["lines"] == 6


def test_a_frame_flown_higher_is_a_scale_outlier() -> None:
    alt = np.full(90, HEIGHT_M)
    alt[37] = HEIGHT_M * 1.2  # 20 % coarser GSD
    alt[52] = HEIGHT_M * 1.05  # within 10 %
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False, alt_m=alt)
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    np.testing.assert_array_equal(scale_outliers(fp, pairs), [37])
    assert pairs.scale_ratio.max() == pytest.approx(1.2, rel=1e-9)


def test_motion_blur_is_speed_times_exposure_over_gsd() -> None:
    frames, station = lawnmower(80.0, 70.0)
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.exposure_source == "exif"
    assert blur.exposure_s is not None and blur.blur_px is not None
    # blur = v t / GSD, the GSD from the planner's formula (Eq. 3-4) at the set height.
    expected_px = SPEED_M_S * (1 / 500) / (CAMERA.gsd_cm(HEIGHT_M) / 100)
    np.testing.assert_allclose(blur.speed_m_s[station], SPEED_M_S, rtol=1e-6)
    np.testing.assert_allclose(blur.blur_px[station], expected_px, rtol=1e-6)
    # A frame in a turn is a line of its own: no neighbour on its line, so no speed to measure.
    assert np.isnan(blur.speed_m_s[~station]).all() and np.isnan(blur.blur_px[~station]).all()
    # Without an EXIF exposure, the camera's shutter.
    no_exif = dataclasses.replace(frames, exposure_s=None)
    shutter = dataclasses.replace(no_exif, camera=dataclasses.replace(CAMERA, shutter_s=1 / 1000))
    from_camera = motion_blur(shutter, fp)
    assert from_camera is not None and from_camera.exposure_source == "camera"
    assert from_camera.blur_px is not None
    np.testing.assert_allclose(from_camera.blur_px[station], expected_px / 2, rtol=1e-6)


def test_without_an_exposure_time_the_speeds_remain() -> None:
    frames, station = lawnmower(80.0, 70.0, exposure_s=None)
    assert frames.camera.shutter_s is None
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None
    assert blur.blur_px is None and blur.exposure_s is None and blur.exposure_source is None
    np.testing.assert_allclose(blur.speed_m_s[station], SPEED_M_S, rtol=1e-6)
    summary = analyse_block(frames, fp, GROUND, FRAME).summary()["motion_blur"]
    assert summary["blur_px"] is None and summary["speed_m_s"]["median"] == pytest.approx(SPEED_M_S)
    assert summary["speed_unknown_frames"] == int((~station).sum())
    # Without capture times there is no speed either.
    assert motion_blur(dataclasses.replace(frames, time_utc_s=None), fp) is None


def line_at(speed_m_s: float, base_m: float, times_s: np.ndarray) -> Frames:
    """One line north, a frame every ``base_m``, taken at ``times_s`` (speed set by the caller)."""
    n = times_s.size
    frames = make_frames(
        np.full(n, ORIGIN_X_M),
        ORIGIN_Y_M + base_m * np.arange(n),
        HEIGHT_M,
        reference=AltitudeReference.REL_HOME,
    )
    return dataclasses.replace(frames, time_utc_s=START_S + times_s, exposure_s=np.full(n, 1 / 500))


def test_a_pause_in_a_line_does_not_lower_the_speed() -> None:
    """Frames every 16 m at 8 m/s (2 s apart); the vehicle hovers 10 s after frame 9, and frame 15
    is taken between two hovers. The slower-neighbour rule gave frames 9 and 10 1.3 m/s."""
    base_m, interval_s = 16.0, 2.0
    steps = np.full(24, interval_s)
    steps[9] += 10.0  # between frames 9 and 10
    steps[14] += 10.0  # between 14 and 15
    steps[15] += 10.0  # between 15 and 16
    frames = line_at(SPEED_M_S, base_m, np.concatenate([[0.0], np.cumsum(steps)]))
    fp = project(frames)
    assert len(np.unique(flight_lines(frames, fp))) == 1
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.blur_px is not None
    # The median interval is 2 s: neighbours further than 6 s do not count.
    assert blur.max_interval_s == pytest.approx(3 * interval_s)
    known = np.arange(25) != 15
    np.testing.assert_allclose(blur.speed_m_s[known], base_m / interval_s, rtol=1e-9)
    assert np.isnan(blur.speed_m_s[15]) and np.isnan(blur.blur_px[15])
    expected_px = SPEED_M_S * (1 / 500) / (CAMERA.gsd_cm(HEIGHT_M) / 100)
    np.testing.assert_allclose(blur.blur_px[known], expected_px, rtol=1e-6)


def test_the_nearer_neighbour_in_time_gives_the_speed() -> None:
    """Frames 16 m apart, 2 s apart up to frame 5 (8 m/s), then 4 s apart (4 m/s, the vehicle
    slowed down): frame 5 takes the speed of its nearer neighbour, frame 4."""
    times = np.concatenate([2.0 * np.arange(6), 10.0 + 4.0 * np.arange(1, 6)])
    frames = line_at(SPEED_M_S, 16.0, times)
    blur = motion_blur(frames, project(frames))
    assert blur is not None
    np.testing.assert_allclose(blur.speed_m_s, np.where(np.arange(11) <= 5, 8.0, 4.0), rtol=1e-9)


def test_frames_of_another_line_are_not_neighbours() -> None:
    """Two lines 60 m apart at 8 m/s, frames 2 s apart; the first frame of the second line is
    taken 1 s after the last of the first (a 60 m/s chord). Nearer in time, but on another line:
    the last frame of the first line keeps the speed of its own line."""
    ys = ORIGIN_Y_M + 16.0 * np.arange(10)
    frames = make_frames(
        np.concatenate([np.full(10, ORIGIN_X_M), np.full(10, ORIGIN_X_M + 60.0)]),
        np.concatenate([ys, ys[::-1]]),
        HEIGHT_M,
        np.repeat([0.0, 180.0], 10),
        reference=AltitudeReference.REL_HOME,
    )
    times = np.concatenate([2.0 * np.arange(10), 19.0 + 2.0 * np.arange(10)])
    frames = dataclasses.replace(frames, time_utc_s=START_S + times, exposure_s=np.full(20, 1 / 500))
    fp = project(frames)
    np.testing.assert_array_equal(flight_lines(frames, fp), np.repeat([0, 1], 10))
    blur = motion_blur(frames, fp)
    assert blur is not None
    np.testing.assert_allclose(blur.speed_m_s, SPEED_M_S, rtol=1e-9)


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


def test_base_height_of_consecutive_and_of_neighbouring_line_pairs() -> None:
    from processing.stereo import pair_kinds

    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    lines = flight_lines(frames, fp)
    along, across = pair_kinds(frames, pairs, lines)
    # Eq. 3-5: B = D (1 - PE / 100) along a line; the line spacing across: B/H over HEIGHT_M.
    nominal = CAMERA.footprint(HEIGHT_M, Orientation.LANDSCAPE)
    assert along.sum() == 6 * 14
    np.testing.assert_allclose(pairs.base_height_ratio[along], nominal.along_m * 0.2 / HEIGHT_M, rtol=1e-6)
    assert across.sum() == 5 * 15  # each station and its neighbour on the next line, once
    np.testing.assert_allclose(pairs.base_height_ratio[across], nominal.across_m * 0.3 / HEIGHT_M, rtol=1e-6)
    # Every other overlapping pair (two stations apart, diagonal, two lines over) is neither.
    assert (~(along | across)).sum() == len(pairs) - 6 * 14 - 5 * 15 > 0


def test_blur_of_a_tilted_frame_is_worst_at_its_near_edge() -> None:
    from test_footprints import _oracle_world_from_camera

    pitch_deg, exposure_s = 30.0, 1 / 100
    y = ORIGIN_Y_M + np.arange(5) * 10.0
    frames = make_frames(
        np.full(5, ORIGIN_X_M), y, HEIGHT_M, 0.0, pitch_deg, reference=AltitudeReference.REL_HOME
    )
    frames = dataclasses.replace(
        frames, time_utc_s=START_S + np.arange(5) * 10.0 / SPEED_M_S, exposure_s=np.full(5, exposure_s)
    )
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.blur_px is not None and blur.blur_centre_px is not None
    d = SPEED_M_S * exposure_s  # metres flown north during the exposure
    f_px = CAMERA.focal_length_mm / CAMERA.pixel_pitch_y_mm
    # The centre: the ground point H tan(p) ahead of the nadir is seen p off the vertical, on the
    # axis; after the camera moves d it is seen atan((H tan p - d) / H) off the vertical, so
    # f tan(that - p) pixels from the centre, along the image's vertical (the track).
    p = math.radians(pitch_deg)
    centre = f_px * abs(math.tan(math.atan((HEIGHT_M * math.tan(p) - d) / HEIGHT_M) - p))
    np.testing.assert_allclose(blur.blur_centre_px, centre, rtol=1e-6)
    # Everywhere: an independent pinhole projection of each ground ring point before and after.
    r = _oracle_world_from_camera(0.0, pitch_deg, 0.0)
    worst = []
    for k in range(5):
        cam = fp.camera_xyz_m[k]
        shifts = []
        for x, yy in fp.xy_m[k]:
            for offset in (0.0, d):
                v = r.T @ (np.array([x, yy, 0.0]) - (cam + np.array([0.0, offset, 0.0])))
                shifts.append((f_px * v[0] / v[2], f_px * v[1] / v[2]))
        pts = np.array(shifts).reshape(-1, 2, 2)
        worst.append(np.hypot(*(pts[:, 1] - pts[:, 0]).T).max())
    np.testing.assert_allclose(blur.blur_px, worst, rtol=1e-6)
    # The near edge (image bottom, closest ground) smears more than the centre: tilt makes it worse.
    assert (blur.blur_px > 1.3 * blur.blur_centre_px).all()
