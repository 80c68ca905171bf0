"""The COLMAP project: database contents read back with sqlite3 (COLMAP's own file format), priors
against geodesic distances between the EXIF positions (read with exifread, a second EXIF
parser), and the pairs against the analytic overlap of nadir rectangles on a synthetic grid."""

from __future__ import annotations

import re
import sqlite3
import struct
from pathlib import Path

import exifread
import numpy as np
import pyexiv2
import pytest
from handoff_grid import F_MM, FOOT_X_M, FOOT_Y_M, H_PX, HEIGHT_M, PITCH_MM, W_PX, grid
from pyproj import Geod
from shared_data import SHARED_DATA

from processing.handoff.block import DEFAULT_SIGMA_XY_M, read_block
from processing.handoff.colmap_project import write_colmap_project
from processing.handoff.errors import HandoffInputError
from processing.handoff.pipeline import Engine, HandoffOptions, handoff
from processing.handoff.prepare import GroundOptions, prepare

_GEOD = Geod(ellps="WGS84")

GARFIELD = SHARED_DATA / "garfield_rgb"
GARFIELD_GROUND_M = 258.0  # as tests/processing/test_check.py: the ground near Garfield Heights


def _analytic_overlap_pct(a: tuple[str, float, float, int], b: tuple[str, float, float, int]) -> float:
    ox = max(0.0, FOOT_X_M - abs(a[1] - b[1]))
    oy = max(0.0, FOOT_Y_M - abs(a[2] - b[2]))
    return 100.0 * ox * oy / (FOOT_X_M * FOOT_Y_M)


def _deg(tags: dict, key: str) -> float:  # type: ignore[type-arg]
    d, m, s = (float(v.num) / float(v.den) for v in tags[key].values)
    return d + m / 60 + s / 3600


def _pairs_file(path: Path) -> set[frozenset[str]]:
    pairs = set()
    for line in path.read_text().splitlines():
        a, b = line.split()
        pairs.add(frozenset((a, b)))
    return pairs


@pytest.mark.parametrize("min_overlap_pct", [5.0, 40.0, 70.0])
def test_pairs_are_the_overlapping_footprints_and_the_line_neighbours(
    tmp_path: Path, min_overlap_pct: float
) -> None:
    frames = grid(tmp_path / "img", lines=4, per_line=6, dx_m=110.0, dy_m=45.0)
    prepared = prepare(
        tmp_path / "img", ground=GroundOptions(ground_elevation_m=0.0), min_overlap_pct=min_overlap_pct
    )
    write_colmap_project(prepared, tmp_path / "work")
    got = _pairs_file(tmp_path / "work" / "pairs.txt")
    expected = set()
    for k, a in enumerate(frames):
        for m, b in enumerate(frames):
            if m <= k:
                continue
            if _analytic_overlap_pct(a, b) >= min_overlap_pct * (1 - 1e-6) or (
                a[3] == b[3] and abs(k - m) <= 2
            ):
                expected.add(frozenset((a[0], b[0])))
    # Overlaps within a hair of the threshold may fall either way (float geometry).
    borderline = {
        frozenset((a[0], b[0]))
        for a in frames
        for b in frames
        if a != b and abs(_analytic_overlap_pct(a, b) - min_overlap_pct) < 1e-3
    }
    assert got - borderline == expected - borderline
    assert len(got) < len(frames) * (len(frames) - 1) // 2


def test_database_holds_cameras_images_and_cartesian_priors(tmp_path: Path) -> None:
    frames = grid(tmp_path / "img", lines=2, per_line=4, dx_m=100.0, dy_m=40.0)
    prepared = prepare(tmp_path / "img", ground=GroundOptions(ground_elevation_m=0.0))
    write_colmap_project(prepared, tmp_path / "work")
    con = sqlite3.connect(tmp_path / "work" / "database.db")
    cams = con.execute(
        "select camera_id, model, width, height, params, prior_focal_length from cameras"
    ).fetchall()
    assert len(cams) == 1
    _, model, width, height, params, prior = cams[0]
    f, cx, cy, k1 = struct.unpack("<4d", params)
    assert (model, width, height, prior) == (2, W_PX, H_PX, 1)  # 2 = SIMPLE_RADIAL
    assert f == pytest.approx(F_MM / PITCH_MM, rel=1e-3)
    assert (cx, cy, k1) == (W_PX / 2, H_PX / 2, 0.0)
    names = dict(con.execute("select image_id, name from images").fetchall())
    assert sorted(names.values()) == sorted(n for n, *_ in frames)
    priors = {}
    for data_id, position, cov, system in con.execute(
        "select corr_data_id, position, position_covariance, coordinate_system from pose_priors"
    ):
        priors[names[data_id]] = (
            np.array(struct.unpack("<3d", position)),
            np.array(struct.unpack("<9d", cov)).reshape(3, 3),
            system,
        )
    assert len(priors) == len(frames)
    assert {p[2] for p in priors.values()} == {1}  # CARTESIAN
    for _, cov, _ in priors.values():
        assert np.allclose(cov, np.diag([1.5**2, 1.5**2, 3.0**2]))
    # The local frame keeps distances: prior separations equal the geodesic distances (EXIF by exifread).
    lonlat = {}
    for name, *_ in frames:
        with open(tmp_path / "img" / name, "rb") as handle:
            tags = exifread.process_file(handle, details=False)

        lonlat[name] = (_deg(tags, "GPS GPSLongitude"), _deg(tags, "GPS GPSLatitude"))
    items = sorted(priors)
    for a in items:
        for b in items:
            if a < b:
                _, _, dist = _GEOD.inv(*lonlat[a], *lonlat[b])
                assert np.linalg.norm(priors[a][0][:2] - priors[b][0][:2]) == pytest.approx(dist, abs=0.01)
        assert priors[a][0][2] == pytest.approx(HEIGHT_M, abs=0.01)


def test_frames_without_position_get_no_prior_and_are_paired_with_all(tmp_path: Path) -> None:
    grid(tmp_path / "img", lines=1, per_line=5, dx_m=100.0, dy_m=40.0, positioned=False)
    block = read_block(tmp_path / "img")
    assert not block.has_position.any()
    assert any("no pose priors" in n for n in block.notes)
    prepared = prepare(tmp_path / "img")
    write_colmap_project(prepared, tmp_path / "work")
    con = sqlite3.connect(tmp_path / "work" / "database.db")
    assert con.execute("select count(*) from pose_priors").fetchone()[0] == 0
    assert len(_pairs_file(tmp_path / "work" / "pairs.txt")) == 10


def test_mixed_cameras_get_one_camera_each(tmp_path: Path) -> None:
    grid(tmp_path / "img", lines=1, per_line=3, dx_m=100.0, dy_m=40.0)
    other = pyexiv2.ImageData((tmp_path / "img" / "F000.jpg").read_bytes())
    other.modify_exif({"Exif.Image.Model": "Grid2", "Exif.Photo.FocalLength": "8/1"})
    (tmp_path / "img" / "F000.jpg").write_bytes(other.get_bytes())
    other.close()
    prepared = prepare(tmp_path / "img", ground=GroundOptions(ground_elevation_m=0.0))
    assert len(prepared.block.intrinsics) == 2
    write_colmap_project(prepared, tmp_path / "work")
    con = sqlite3.connect(tmp_path / "work" / "database.db")
    focals = sorted(struct.unpack("<4d", p)[0] for (p,) in con.execute("select params from cameras"))
    assert focals == pytest.approx([F_MM / PITCH_MM, 8.0 / PITCH_MM], rel=1e-3)


def test_existing_work_is_refused_and_nothing_is_half_written(tmp_path: Path) -> None:
    grid(tmp_path / "img", lines=1, per_line=3, dx_m=100.0, dy_m=40.0)
    work = tmp_path / "work"
    work.mkdir()
    (work / "keep.txt").write_text("x")
    with pytest.raises(Exception, match="--overwrite"):
        handoff(
            tmp_path / "img",
            work,
            HandoffOptions(engine=Engine.COLMAP, ground=GroundOptions(ground_elevation_m=0.0)),
        )
    assert sorted(p.name for p in work.iterdir()) == ["keep.txt"]
    # A failure (a ground above the cameras) leaves no staging folder behind.
    with pytest.raises(Exception, match="check the ground elevation"):
        handoff(
            tmp_path / "img",
            tmp_path / "new",
            HandoffOptions(engine=Engine.COLMAP, ground=GroundOptions(ground_elevation_m=500.0)),
        )
    assert not (tmp_path / "new").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".new")]


def test_garfield_project_uses_the_pix4d_accuracy_tags(tmp_path: Path) -> None:
    prepared = prepare(GARFIELD, ground=GroundOptions(ground_elevation_m=GARFIELD_GROUND_M))
    assert prepared.block.sigma_source.startswith("the images' XMP")
    first = GARFIELD / prepared.block.names[0]
    xmp = first.read_bytes().decode("latin-1")
    tagged = float(re.search(r'GPSXYAccuracy="([0-9.]+)"', xmp).group(1))  # type: ignore[union-attr]
    assert prepared.block.sigma_xy_m[0] == pytest.approx(tagged)
    assert prepared.block.sigma_xy_m[0] != DEFAULT_SIGMA_XY_M
    assert len(prepared.pairs) < 378


def test_an_image_folder_with_no_jpeg_is_refused(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(Exception, match="no JPEG"):
        prepare(tmp_path / "empty")
    assert HandoffInputError.exit_code == 2
