"""The coverage check end to end: a plan that passes, the same plan without a line that fails
with the gap where the line was, a re-fly mission that closes it, the real Garfield images, and
the report folder read back with real parsers (rasterio, json, matplotlib's PNG reader).
"""

from __future__ import annotations

import json
import math
import re
import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
import pytest
import rasterio
import shapely
import shapely.geometry
from matplotlib.image import imread
from shared_data import SHARED_DATA
from test_verdict import _gap

from acquisition.simulator.flight import FlightSimulator
from planner.errors import OutputExistsError
from planner.mission import Autopilot, VehicleType
from planner.plan_folder import write_outputs
from planner.spec import parse_spec
from planner.survey import plan_polygons
from processing.check import default_cell_m, exact_gaps, run_check
from processing.check_result import CheckResult
from processing.check_stereo import STEREO_GOOD
from processing.distribution import Distribution
from processing.errors import ProcessingError
from processing.frames import AltitudeReference, Frames
from processing.ground_choice import ground_from_options
from processing.image_frames import read_image_frames
from processing.plan_frames import frames_from_plan
from processing.refly import refly_mission, refly_parameters
from processing.report import REPORT_FILES, write_report
from processing.track import frames_from_track
from processing.verdict import Thresholds, judge

GARFIELD = SHARED_DATA / "garfield_rgb"
#: Garfield Heights lies at 253 m AMSL where it borders Cleveland, where the frames are: with
#: altitudes of 348-354 m AMSL the camera is about 90-96 m above the ground (no height above
#: ground is recorded in the images).
GARFIELD_GROUND_M = 258.0
#: Coarse cells keep the tests fast; the gully's frames are 55 x 83 m.
CELL_M = 4.0


def subset(frames: Frames, keep: np.ndarray) -> Frames:
    """The rows ``keep`` (bool mask) of ``frames``."""
    index = np.flatnonzero(keep)

    def take(a: Any) -> Any:
        return None if a is None else np.asarray(a)[index]

    return replace(
        frames,
        name=tuple(frames.name[k] for k in index),
        lon_deg=frames.lon_deg[index],
        lat_deg=frames.lat_deg[index],
        alt_m=frames.alt_m[index],
        yaw_deg=frames.yaw_deg[index],
        pitch_deg=frames.pitch_deg[index],
        roll_deg=frames.roll_deg[index],
        time_utc_s=take(frames.time_utc_s),
        exposure_s=take(frames.exposure_s),
        line_index=take(frames.line_index),
    )


def _check_plan(folder: Path, **kwargs: Any) -> CheckResult:
    frames, info = frames_from_plan(folder)
    choice = ground_from_options(frames=frames)
    return run_check(
        choice.frames,
        ground=choice.ground,
        plan=info,
        cell_m=CELL_M,
        ground_description=choice.description,
        **kwargs,
    )


@pytest.fixture(scope="module")
def gully_result(gully: tuple[Any, Path]) -> CheckResult:
    return _check_plan(gully[1])


def test_the_plan_passes_with_its_own_overlaps(gully_result: CheckResult) -> None:
    r = gully_result
    assert r.passed and r.reasons == ()
    assert r.seen_pct[1] == 100.0 and r.gaps == ()
    assert r.area_source.startswith("the plan's area")
    # The plan was made for 80 % endlap and 70 % sidelap (Eq. 3-5): measured on its footprints.
    assert r.stereo.forward_overlap_pct is not None and r.stereo.side_overlap_pct is not None
    assert r.stereo.forward_overlap_pct.median == pytest.approx(80.0, abs=1.0)
    assert r.stereo.side_overlap_pct.median == pytest.approx(70.0, abs=1.0)
    # Nadir only: the doming warning, and no convergent frame.
    assert r.stereo.doming_risk and any("doming" in w for w in r.warnings)
    # GSD from Eq. 3-4 at the plan's height: 2.4 cm (stations.geojson keeps altitudes to 1 cm).
    expected = r.frames.camera.gsd_cm(r.plan.planned.summary.altitude_agl_m)  # type: ignore[union-attr]
    assert np.nanmedian(r.gsd_cm) == pytest.approx(expected, abs=expected * 0.01 / 74.0)
    assert r.stereo.good_pair_pct is not None and r.stereo.good_pair_pct > 99.0
    assert (r.stereo.stereo_class[r.in_area] == STEREO_GOOD).mean() > 0.99
    # The plan's area in the local frame equals the one the planner measured.
    assert r.area_m2 == pytest.approx(r.plan.planned.summary.area_m2, rel=0.01)  # type: ignore[union-attr]


@pytest.fixture(scope="module")
def without_first_line(
    gully: tuple[Any, Path], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, list[dict[str, Any]]]:
    """The plan folder without the stations of the first line flown (the edge line nearest home)."""
    _, folder = gully
    copy = tmp_path_factory.mktemp("gully-minus") / "plan"
    shutil.copytree(folder, copy)
    data = json.loads((copy / "stations.geojson").read_text())
    first = data["features"][0]["properties"]
    line = (first["pass"], first["line"])
    removed = [f for f in data["features"] if (f["properties"]["pass"], f["properties"]["line"]) == line]
    data["features"] = [f for f in data["features"] if f not in removed]
    (copy / "stations.geojson").write_text(json.dumps(data))
    return copy, removed


@pytest.fixture(scope="module")
def missing_line_result(without_first_line: tuple[Path, list[dict[str, Any]]]) -> CheckResult:
    return _check_plan(without_first_line[0])


def test_a_missing_line_fails_with_the_gap_where_it_was(
    gully: tuple[Any, Path], missing_line_result: CheckResult, without_first_line: tuple[Path, Any]
) -> None:
    plan, _ = gully
    r = missing_line_result
    assert not r.passed
    assert r.gaps and any("seen by any frame" in reason or "gap" in reason for reason in r.reasons)
    removed = without_first_line[1]
    removed_index = {f["properties"]["station"] for f in removed}
    st = plan.stations
    keep = np.array([k not in removed_index for k in range(len(st))])
    kept_fp = shapely.union_all(shapely.polygons(st.footprint_xy_m[keep]))
    removed_fp = shapely.union_all(shapely.polygons(st.footprint_xy_m[~keep]))
    area_xy = plan.area_xy
    # The true gap: the area covered by the removed line only.
    truth = area_xy.difference(kept_fp)
    assert truth.area > 100.0
    found = shapely.union_all([plan.frame.geometry_to_xy(g.polygon_lonlat) for g in r.gaps])
    # Found where the line was, within the raster's resolution (cells of CELL_M).
    assert found.difference(removed_fp.buffer(CELL_M)).area == pytest.approx(0.0, abs=1e-6)
    assert truth.symmetric_difference(found).area < CELL_M * truth.length
    assert r.gap_area_m2 == pytest.approx(truth.area, rel=0.15)
    gap_pct = 100.0 * truth.area / area_xy.area
    assert r.seen_pct[1] == pytest.approx(100.0 - gap_pct, abs=0.3)


@pytest.mark.slow  # plans a mission and runs a second check: about 4 s
def test_the_refly_mission_covers_the_gaps(
    gully: tuple[Any, Path],
    missing_line_result: CheckResult,
    without_first_line: tuple[Path, Any],
    tmp_path: Path,
) -> None:
    plan, _ = gully
    r = missing_line_result
    params = refly_parameters(r)
    assert params.camera == plan.camera and params.altitude_agl_m == pytest.approx(
        plan.summary.altitude_agl_m
    )
    refly = refly_mission([g.polygon_lonlat for g in r.gaps], params)
    # Its stations' footprints cover every gap polygon.
    cover = shapely.union_all(shapely.polygons(refly.stations.footprint_xy_m))
    for gap in r.gaps:
        assert cover.contains(refly.frame.geometry_to_xy(gap.polygon_lonlat))
    assert len(refly.stations) < len(plan.stations) / 3
    # And the check itself agrees: the flown frames plus the re-fly leave no gap.
    write_outputs(refly, tmp_path / "refly")
    flown, info = frames_from_plan(without_first_line[0])
    extra, _ = frames_from_plan(tmp_path / "refly")
    assert extra.camera == flown.camera
    columns: dict[str, Any] = {
        key: np.concatenate([getattr(flown, key), getattr(extra, key)])
        for key in ("lon_deg", "lat_deg", "alt_m", "yaw_deg", "pitch_deg", "roll_deg")
    }
    assert flown.line_index is not None and extra.line_index is not None
    both = replace(
        flown,
        name=flown.name + tuple(f"refly-{n}" for n in extra.name),
        line_index=np.concatenate([flown.line_index, extra.line_index + 1000]),
        **columns,
    )
    choice = ground_from_options(frames=both)
    closed = run_check(choice.frames, ground=choice.ground, plan=info, cell_m=CELL_M)
    assert closed.gaps == () and closed.seen_pct[1] == 100.0


@pytest.fixture(scope="module")
def garfield() -> Any:
    return read_image_frames(GARFIELD)


@pytest.fixture(scope="module")
def garfield_result(garfield: Any) -> CheckResult:
    choice = ground_from_options(frames=garfield.frames, ground_elevation_m=GARFIELD_GROUND_M)
    return run_check(
        choice.frames, ground=choice.ground, ground_description=choice.description, notes=garfield.notes
    )


def test_garfield_images(garfield_result: CheckResult) -> None:
    r = garfield_result
    assert len(r.frames) == 28
    assert r.area_source.startswith("the block the flight spans")
    # Heights above the given ground; GSD by Eq. 3-4 within the few percent the tilts add.
    h = r.height_agl_m
    assert h.min() == pytest.approx(347.723 - GARFIELD_GROUND_M, abs=0.01)
    cam = r.frames.camera
    np.testing.assert_allclose(r.gsd_cm, [cam.gsd_cm(x) for x in h], rtol=0.04)
    # The block itself is seen by every frame's neighbours (large frames, 95 m up) ...
    assert r.seen_pct[1] == 100.0 and r.gaps == ()
    # ... but the sparse subset leaves frames 5 s apart at 11-14 m/s: about 40 % endlap and B/H
    # 0.6 between consecutive frames, and COLMAP registers only 12 of the 28 frames in its largest
    # model (sfap handoff --to colmap --run). The check fails it for that, not for blur: the
    # 1/333 s exposure smears 1.5-1.8 px, flagged (above 0.5 px), not failed (below 2 px).
    assert not r.passed
    assert any(x.startswith("median forward overlap (endlap)") and "below the 60 %" in x for x in r.reasons)
    assert any("base-height ratio of consecutive frames of a line" in x for x in r.reasons)
    assert not any("motion blur" in x for x in r.reasons)
    # Passes minutes apart overlap with short bases (B/H 0.1-0.4 across lines) and cover all of it
    # with good pairs: what breaks the block is the endlap along its lines, not that share.
    assert r.base_height_across_lines is not None and r.base_height_across_lines.median < 0.54
    assert r.stereo.good_pair_pct is not None and r.stereo.good_pair_pct >= r.thresholds.min_good_pair_pct
    assert any("motion blur above 0.5 px" in w for w in r.warnings)
    assert r.stereo.blur_px is not None and 1.4 < np.nanmax(r.stereo.blur_px) < r.thresholds.fail_blur_px
    blurred = [f for f in r.flagged if f.kind == "blur"]
    assert blurred and r.stereo.blur_px is not None
    for flag in blurred:
        k = r.frames.name.index(flag.name)
        assert r.stereo.blur_px[k] > r.thresholds.max_blur_px


def test_a_high_endlap_block_has_its_stereo_from_frames_further_apart(tmp_path: Path) -> None:
    """92 % endlap with the Sequoia (sensor 4.63 mm along the track, f 4.88 mm): consecutive frames
    have B/H 0.08 x 0.949 = 0.076 (REFERENCES.md section 1), under the 0.1 of a good pair, but the
    frames two and more apart on the line (0.15-0.5) and the neighbouring lines' (0.3 x 6.175 /
    4.88 = 0.38) are good: the block passes on stereo; judging consecutive pairs alone would fail
    it."""
    spec = parse_spec(
        {
            "name": "high-endlap",
            "area": "square.geojson",
            "camera": {"model": "parrot-sequoia-rgb"},
            "survey": {
                "altitude_agl_m": 60.0,
                "front_overlap_pct": 92,
                "side_overlap_pct": 70,
                "speed_m_s": 2.0,
            },
            "vehicle": {"home": [42.0, -1.5], "home_alt_amsl_m": 300.0},
        },
        tmp_path / "square.toml",
    )
    write_outputs(
        plan_polygons(spec, [shapely.box(-1.4995, 42.0003, -1.4975, 42.0018)], []), tmp_path / "plan"
    )
    r = _check_plan(tmp_path / "plan")
    along = r.base_height_along_line
    # Within 5 %: the planner spaces the stations evenly along each line, a little closer.
    assert along is not None and along.median == pytest.approx(0.08 * 4.631 / 4.88, rel=0.05)
    assert along.median < r.thresholds.min_base_height_ratio
    assert r.stereo.good_pair_pct is not None and r.stereo.good_pair_pct >= r.thresholds.min_good_pair_pct
    assert not any("base-height" in x for x in r.reasons), r.reasons


def test_garfield_endlap_and_base_height_agree_with_the_capture_numbers(garfield_result: CheckResult) -> None:
    """Independent oracle: the Sequoia numbers every capture, so consecutive frames are the ones whose
    numbers differ by 1. Their base (geodesic distance and altitude difference), the height above the
    given ground and Eq. 3-5 with the sensor's longer side along the track (the most favourable
    orientation) bound the endlap; B/H is base over height."""
    r = garfield_result
    number = np.array([int(name.split("_")[3]) for name in r.frames.name])
    geod = pyproj.Geod(ellps="WGS84")
    cam = r.frames.camera
    longer_side_mm = max(cam.sensor_width_mm, cam.sensor_height_mm)
    endlap_pct, ratio = [], []
    for k in range(len(number)):
        for other in np.flatnonzero(number == number[k] + 1):
            _, _, horizontal_m = geod.inv(
                r.frames.lon_deg[k], r.frames.lat_deg[k], r.frames.lon_deg[other], r.frames.lat_deg[other]
            )
            base_m = math.hypot(horizontal_m, r.frames.alt_m[k] - r.frames.alt_m[other])
            height_m = 0.5 * (r.frames.alt_m[k] + r.frames.alt_m[other]) - GARFIELD_GROUND_M
            ratio.append(base_m / height_m)
            endlap_pct.append(100.0 * (1.0 - base_m / (height_m * longer_side_mm / cam.focal_length_mm)))
    assert len(ratio) >= 8
    along = r.base_height_along_line
    assert along is not None and along.median == pytest.approx(float(np.median(ratio)), rel=0.05)
    assert np.median(ratio) > r.thresholds.max_base_height_ratio
    # Even with the longer side along the track the endlap stays under the 60 % floor.
    assert np.median(endlap_pct) < r.thresholds.min_forward_overlap_pct
    assert r.stereo.forward_overlap_pct is not None
    assert r.stereo.forward_overlap_pct.median <= np.median(endlap_pct) + 2.0


def test_garfield_speeds_come_from_consecutive_captures(garfield_result: CheckResult) -> None:
    """The Sequoia numbers every capture (IMG_..._0012_RGB.JPG): a measured speed is the step to
    the next or previous capture, never across the frames the subset dropped, a turn or a pause
    (the slower-neighbour rule gave 0.2 m/s here). The aircraft cruised at 10-15 m/s."""
    r = garfield_result
    assert r.stereo.speed_m_s is not None and r.stereo.blur_px is not None
    number = np.array([int(name.split("_")[3]) for name in r.frames.name])
    t = r.frames.time_utc_s
    assert t is not None
    known = np.flatnonzero(np.isfinite(r.stereo.speed_m_s))
    assert known.size >= 10
    geod = pyproj.Geod(ellps="WGS84")
    for k in known:
        assert 10.0 < r.stereo.speed_m_s[k] < 15.0
        steps = []
        for other in np.flatnonzero(np.abs(number - number[k]) == 1):
            _, _, horizontal_m = geod.inv(
                r.frames.lon_deg[k], r.frames.lat_deg[k], r.frames.lon_deg[other], r.frames.lat_deg[other]
            )
            dist_m = math.hypot(horizontal_m, r.frames.alt_m[k] - r.frames.alt_m[other])
            steps.append(dist_m / abs(t[k] - t[other]))
        assert steps and min(abs(v - r.stereo.speed_m_s[k]) for v in steps) < 0.01 * r.stereo.speed_m_s[k]
    # Unknown speeds leave blur unknown, and the report says how many.
    assert np.isnan(r.stereo.blur_px[np.isnan(r.stereo.speed_m_s)]).all()
    unknown = int(np.isnan(r.stereo.speed_m_s).sum())
    assert any(f"ground speed unknown for {unknown} of 28 frames" in note for note in r.notes)
    figures = dict(r.key_figures())
    assert f"unknown for {unknown} frames" in figures["ground speed"]
    assert f"blur not computed for {unknown} frames" in figures["motion blur"]


def test_garfield_gap_where_the_subset_has_no_frames(garfield: Any, garfield_result: CheckResult) -> None:
    """Drop the frames north of the block's middle and judge the whole block: the gap is in the
    north, outside every remaining footprint, inside the dropped ones. (The frames are 90-120 m
    wide at 95 m above ground, so the block needs half of them gone to open a gap.)"""
    frames = garfield.frames
    north = frames.lat_deg > np.median(frames.lat_deg)
    assert north.sum() == 14
    choice = ground_from_options(frames=subset(frames, ~north), ground_elevation_m=GARFIELD_GROUND_M)
    r = run_check(choice.frames, ground=choice.ground, area=garfield_result.area_lonlat, cell_m=1.0)
    assert r.gaps and not r.passed
    full = garfield_result
    dropped = [full.frames.name.index(n) for n in np.asarray(frames.name)[north]]
    kept_fp = shapely.union_all(shapely.polygons(r.footprints_xy))
    dropped_fp = shapely.union_all(shapely.polygons(full.footprints_xy[dropped]))
    for gap in r.gaps:
        poly = r.frame.geometry_to_xy(gap.polygon_lonlat)
        assert poly.intersection(kept_fp).area < 2.0 * poly.length  # a cell's width along its edge
        assert dropped_fp.buffer(1.0).contains(poly)
        assert gap.centroid_lat_deg > np.median(frames.lat_deg)


def test_report_folder(garfield_result: CheckResult, tmp_path: Path) -> None:
    r = garfield_result
    out = tmp_path / "report"
    written = write_report(r, out)
    assert sorted(p.name for p in written) == sorted(REPORT_FILES)
    assert all(p.is_file() for p in written)
    data = json.loads((out / "report.json").read_text())
    assert data["verdict"] == "fail" and data["exit_code"] == 1 and data["reasons"] == list(r.reasons)
    assert data["stereo"]["good_pair_basis"] == "frames on one line or neighbouring lines"
    assert data["frames"]["count"] == 28 and data["frames"]["camera_id"] == "parrot-sequoia-rgb"
    assert data["coverage"]["seen_by_at_least_pct"]["1"] == r.seen_pct[1]
    assert len(data["per_frame"]) == 28
    with rasterio.open(out / "coverage.tif") as tif:
        # A named CRS: Cleveland, Ohio is in UTM zone 17 N; report.json names the same one.
        assert tif.crs.to_epsg() == 32617
        assert data["area"]["crs"].split(" ")[0] == "EPSG:32617"
        assert data["area"]["extent_m"] == pytest.approx(list(tif.bounds), abs=2 * r.cell_m)
        assert tif.nodata == -1 and tif.descriptions[0].startswith("views")
        assert tif.transform.a == r.cell_m
        values = tif.read(1)
        rows, cols = np.indices(values.shape)
        east, north = rasterio.transform.xy(tif.transform, rows.ravel(), cols.ravel())
    # Independently: each UTM cell centre, through pyproj, into the check's frame and its grid.
    to_lonlat = pyproj.Transformer.from_crs(32617, 4326, always_xy=True)
    lon, lat = to_lonlat.transform(np.asarray(east), np.asarray(north))
    x, y = r.frame.to_xy(lon, lat)
    west, _, _, north_edge = r.grid.bounds
    col = np.floor((np.asarray(x) - west) / r.cell_m).astype(int)
    row = np.floor((north_edge - np.asarray(y)) / r.cell_m).astype(int)
    inside = (row >= 0) & (row < r.grid.rows) & (col >= 0) & (col < r.grid.cols)
    expected = np.full(values.size, -1)
    sel = np.flatnonzero(inside)
    in_area = r.in_area[row[sel], col[sel]]
    expected[sel[in_area]] = r.view_count[row[sel], col[sel]][in_area]
    # Nearest-neighbour resampling agrees cell for cell away from cell boundaries.
    assert np.mean(values.ravel() == expected) > 0.97
    assert ((values == -1).sum() > 0) and (values[values >= 0].min() >= 0)
    footprints = json.loads((out / "footprints.geojson").read_text())
    assert len(footprints["features"]) == 28
    for feature, ring in zip(footprints["features"], r.footprints_lonlat, strict=True):
        written = shapely.geometry.shape(feature["geometry"])
        assert written.exterior.is_ccw  # RFC 7946
        # Coordinates are rounded to 1e-8 deg: the shapes differ by at most that along the edge.
        assert written.symmetric_difference(shapely.Polygon(ring)).area < 1e-8 * written.length
    assert json.loads((out / "gaps.geojson").read_text())["features"] == []
    page = (out / "report.html").read_text()
    assert page.index("FAIL") < page.index("Key figures")  # the verdict first
    assert page.index("median forward overlap (endlap)") < page.index("Key figures")  # and its reasons
    for name in ("view_count.png", "gaps.png", "gsd.png", "base_height.png"):
        assert f'src="{name}"' in page
        image = imread(out / name)
        assert image.shape[0] > 500 and image.shape[1] > 600
    for flag in r.flagged:
        assert flag.name in page
    with pytest.raises(OutputExistsError, match="--overwrite"):
        write_report(r, out)
    write_report(r, out, overwrite=True)


@pytest.mark.slow  # renders the maps of 538 frames: about 4 s
def test_report_of_a_failing_plan_lists_its_gaps(missing_line_result: CheckResult, tmp_path: Path) -> None:
    r = missing_line_result
    write_report(r, tmp_path / "r")
    gaps = json.loads((tmp_path / "r" / "gaps.geojson").read_text())["features"]
    assert [g["properties"]["gap"] for g in gaps] == [g.index for g in r.gaps]
    for feature, gap in zip(gaps, r.gaps, strict=True):
        assert feature["properties"]["area_m2"] == pytest.approx(gap.area_m2, abs=0.01)
        written = shapely.geometry.shape(feature["geometry"])
        assert written.symmetric_difference(gap.polygon_lonlat).area < 1e-8 * written.length
    page = (tmp_path / "r" / "report.html").read_text()
    assert "Gaps" in page and f"{r.gaps[0].area_m2:,.0f}" in page
    with rasterio.open(tmp_path / "r" / "coverage.tif") as tif:
        values = tif.read(1)
    # Inside the area a gap is 0 views, a value; outside the area is nodata.
    assert (values == 0).sum() > 0 and (values == -1).sum() > 0 and tif.nodata == -1


def test_judge_each_threshold() -> None:
    t = Thresholds()
    full = {1: 100.0, 2: 100.0, 3: 100.0, 5: 100.0, 9: 100.0}
    base: dict[str, Any] = {
        "thresholds": t, "seen_pct": full, "gaps": [], "forward_overlap_pct": None, "side_overlap_pct": None,
        "plan": None, "good_pair_pct": 100.0, "blurred_count": 0, "frame_count": 100,
    }  # fmt: skip
    assert judge(**base) == ()
    assert "seen by any frame" in judge(**{**base, "seen_pct": {**full, 1: 98.9}})[0]
    assert "3 or more" in judge(**{**base, "seen_pct": {**full, 3: 89.0}})[0]
    assert "larger than 25 m2" in judge(**{**base, "gaps": [_gap(30.0)]})[0]
    assert judge(**{**base, "gaps": [_gap(20.0)]}) == ()
    assert "base-height" in judge(**{**base, "good_pair_pct": 80.0})[0]
    assert judge(**{**base, "blurred_count": 5}) == ()  # 5 % allowed
    assert "motion blur" in judge(**{**base, "blurred_count": 6})[0]
    # Frames without a speed count as sharp, and the reason says how many there were.
    assert "unknown" not in judge(**{**base, "blurred_count": 6})[0]
    assert "blur unknown for 3 frames" in judge(**{**base, "blurred_count": 6, "blur_unknown_count": 3})[0]
    assert judge(**{**base, "blur_unknown_count": 90}) == ()


def test_overlap_against_the_plan(gully_result: CheckResult) -> None:
    plan = gully_result.plan
    assert plan is not None
    low = Distribution.of(np.full(10, plan.planned.summary.front_overlap_pct - 10.5))
    ok = Distribution.of(np.full(10, plan.planned.summary.front_overlap_pct - 9.5))
    reasons = judge(
        thresholds=Thresholds(), seen_pct={k: 100.0 for k in (1, 2, 3, 5, 9)}, gaps=[],
        forward_overlap_pct=low, side_overlap_pct=ok, plan=plan, good_pair_pct=None,
        blurred_count=0, frame_count=10,
    )  # fmt: skip
    assert len(reasons) == 1 and "forward overlap 70 %" in reasons[0] and "planned 80 %" in reasons[0]


def test_thresholds_are_validated() -> None:
    with pytest.raises(ProcessingError, match="min_seen_1_pct"):
        Thresholds(min_seen_1_pct=101.0)
    with pytest.raises(ProcessingError, match="B/H range"):
        Thresholds(min_base_height_ratio=0.6, max_base_height_ratio=0.5)
    with pytest.raises(ProcessingError, match="max_blur_px"):
        Thresholds(max_blur_px=0.0)


def test_default_cell_size() -> None:
    assert default_cell_m(55.3, 165_000.0) == 2.0  # 1.1 m rounded up to 1-2-5
    assert default_cell_m(100.0, 1e4) == 2.0
    assert default_cell_m(10.0, 1e4) == 0.2
    # 2 km2 would need more than 4 million cells of 0.5 m: coarser.
    cell = default_cell_m(25.0, 2e6)
    assert 2e6 / cell**2 <= 4_000_000 and cell == 1.0


@pytest.mark.slow  # flies the 565-photo mission in the simulator and checks twice: about 8 s
def test_plan_check_and_flown_check_agree_on_a_simulated_flight(
    gully: tuple[Any, Path], gully_result: CheckResult
) -> None:
    """Fly the gully mission with the simulated vehicle (ArduPilot rules, GPS noise of 0.3 m),
    take its photos' reported positions as frames (no attitude recorded: nadir along the track),
    and check them against the plan: the same verdict and the same figures as the plan check."""
    plan, folder = gully
    sim = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.MULTIROTOR, home=plan.home)
    sim.set_mission(list(plan.mission.items))
    sim.step(2.0)
    assert sim.arm() == (True, "") and sim.set_mode(1, 3)
    while not sim.has_landed_after_flight and sim.time_s < 5000:
        sim.step(2.0)
    shots = sim.shots
    assert len(shots) == len(plan.stations)
    flown = frames_from_track(
        name=[f"shot-{s.index}" for s in shots],
        lon_deg=np.array([s.reported_lon_deg for s in shots]),
        lat_deg=np.array([s.reported_lat_deg for s in shots]),
        alt_m=np.array([s.reported_alt_rel_home_m for s in shots]),
        alt_reference=AltitudeReference.REL_HOME,
        camera=plan.camera,
        time_utc_s=np.array([s.utc_s for s in shots]),
    )
    _, info = frames_from_plan(folder)
    choice = ground_from_options(frames=flown)
    r = run_check(choice.frames, ground=choice.ground, plan=info, cell_m=CELL_M)
    planned = gully_result
    assert r.passed and planned.passed and r.gaps == ()
    # GPS noise moves the block's edge frames by a few decimetres: shares agree within a point.
    for k in (1, 2, 3, 5):
        assert r.seen_pct[k] == pytest.approx(planned.seen_pct[k], abs=1.0)
    assert r.stereo.forward_overlap_pct is not None and planned.stereo.forward_overlap_pct is not None
    assert r.stereo.side_overlap_pct is not None and planned.stereo.side_overlap_pct is not None
    assert r.stereo.forward_overlap_pct.median == pytest.approx(
        planned.stereo.forward_overlap_pct.median, abs=1.0
    )
    assert r.stereo.side_overlap_pct.median == pytest.approx(planned.stereo.side_overlap_pct.median, abs=1.0)
    assert r.stereo.good_pair_pct == pytest.approx(planned.stereo.good_pair_pct, abs=1.0)
    # No exposure time is known for this camera (the plan's database entry has none): the
    # check says so rather than guessing a blur, but measures the speeds, which are the plan's.
    assert plan.camera.shutter_s is None and r.stereo.blur_px is None
    assert r.stereo.speed_m_s is not None and np.isfinite(r.stereo.speed_m_s).all()
    np.testing.assert_allclose(r.stereo.speed_m_s, plan.summary.speed_m_s, rtol=0.05)
    figures = dict(r.key_figures())
    assert "no exposure time" in figures["motion blur"]
    assert figures["ground speed"].startswith(f"median {plan.summary.speed_m_s:.1f} m/s")
    assert planned.stereo.speed_m_s is None and dict(planned.key_figures())["ground speed"].startswith(
        "not measured"
    )


# --- thresholds at their boundaries (exactly at, just below, just above) ---

T = Thresholds()


@pytest.mark.parametrize(("delta", "kept"), [(-0.001, False), (0.0, True), (0.001, True)])
def test_smallest_gap_reported(delta: float, kept: bool) -> None:
    # A 10 m x 10 m area, one footprint covering all of it but a strip of min_gap_area_m2 + delta.
    width = (T.min_gap_area_m2 + delta) / 10.0
    area = shapely.box(0, 0, 10, 10)
    footprint = shapely.box(width, -1, 11, 11)
    gaps = exact_gaps(area, [footprint], min_area_m2=T.min_gap_area_m2)
    assert (len(gaps) == 1) is kept
    if kept:
        assert gaps[0].area == pytest.approx(T.min_gap_area_m2 + delta, abs=1e-9)


def test_a_diagonal_sliver_is_one_gap_with_its_true_area() -> None:
    # Two footprints whose edges run diagonally 0.3 m apart across a 100 m square: on a 1 m grid
    # the sliver is a chain of cells touching at corners; here it is one gap of 0.3 x 141.4 m.
    area = shapely.box(0, 0, 100, 100)
    lower = shapely.Polygon(
        [(-1, -1), (101, -1), (101, 101 - 0.3 * math.sqrt(2)), (-1, -1 - 0.3 * math.sqrt(2))]
    )
    lower = shapely.Polygon([(-10, -10), (110, -10), (110, 110)])  # below the diagonal y = x
    upper = shapely.affinity.translate(shapely.Polygon([(-10, -10), (-10, 110), (110, 110)]), -0.3, 0.3)
    gaps = exact_gaps(area, [lower, upper], min_area_m2=1.0)
    assert len(gaps) == 1
    # Strip between y = x and y = x + 0.6, clipped to the square: 0.6 x 100 minus two corner triangles.
    assert gaps[0].area == pytest.approx(0.6 * 100 - 0.6**2 / 2 * 2 / 2, rel=1e-3)


def test_a_long_list_of_frames_left_out_is_one_summarised_line() -> None:
    """A card of 123 placeholder positions, 20 climbing frames, 3 on the ground and 2 in transit
    (the issue's card gave a 10,916-character line): one line of a few hundred characters, every
    kind counted, the counts adding up, the full list left to report.json."""
    from processing.survey_frames import left_out_summary

    left = (
        [
            (f"IMG_{k:04d}.JPG", f"placeholder position at 0/0 (lat 0.0000000, lon 0.{k:07d}): no fix")
            for k in range(123)
        ]
        + [
            (f"C{k:03d}.JPG", f"climbing: {30 + k:.1f} m above the ground, -{k}.0 m off the cruise")
            for k in range(20)
        ]
        + [
            (f"G{k}.JPG", f"on the ground: {k:.1f} m above it (take-off, landing or the pad)")
            for k in range(3)
        ]
        + [(f"T{k}.JPG", f"in transit: {900 + k} m from the nearest other frame") for k in range(2)]
    )
    line = left_out_summary(left)
    assert len(line) < 800, len(line)
    counts = {
        kind: int(n)
        for n, kind in re.findall(r"(\d+) (placeholder position at 0/0|climbing|on the ground) \(", line)
    }
    assert counts == {"placeholder position at 0/0": 123, "climbing": 20, "on the ground": 3}
    assert "2 in transit (T0.JPG, T1.JPG;" in line and "report.json" in line
    assert "IMG_0003.JPG" not in line  # three names a kind
