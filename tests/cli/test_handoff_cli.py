"""`sfap handoff` through the CLI: every engine's folder, and bad input with exit codes."""

from __future__ import annotations

import json
import math
import statistics
from pathlib import Path

import exifread
import pytest
from click.testing import CliRunner
from handoff_grid import FOOT_X_M, FOOT_Y_M, HEIGHT_M, grid
from pyproj import CRS

from sfap.cli import cli


def _gcp_csv(
    path: Path, frames: list[tuple[str, float, float, int]], images: Path, alt_m: float = 0.0
) -> Path:
    # Three points, each in two frames, at pixel positions inside the 320 x 240 frames.
    rows = ["name,lon_deg,lat_deg,alt_m,image,x_px,y_px"]
    for k in range(3):
        for name, *_ in frames[k : k + 2]:
            alt = alt_m + k if alt_m else 0.0  # all 0.0: OpenDroneMap's unknown heights
            rows.append(f"g{k},7.00{k}1,45.00{k}1,{alt},{name},{100 + 10 * k},{80 + 5 * k}")
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture
def block(tmp_path: Path) -> tuple[Path, list[tuple[str, float, float, int]]]:
    frames = grid(tmp_path / "img", lines=3, per_line=5, dx_m=110.0, dy_m=45.0)
    return tmp_path / "img", frames


def _run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_colmap_project_and_json(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    code, out, err = _run(
        "handoff",
        str(images),
        "--to",
        "colmap",
        "--ground-elevation-m",
        "0",
        "-o",
        str(tmp_path / "w"),
        "--json",
    )
    assert code == 0, err
    data = json.loads(out)
    assert data["project"]["images"] == len(frames)
    assert {p.name for p in (tmp_path / "w").iterdir()} >= {
        "database.db",
        "pairs.txt",
        "project.json",
        "images",
        "report.json",
    }
    assert CRS.from_proj4(data["project"]["local_frame"]["proj"]).is_projected
    # Again without --overwrite: refused, exit 2, the project untouched.
    before = (tmp_path / "w" / "pairs.txt").read_bytes()
    code, out, err = _run(
        "handoff", str(images), "--to", "colmap", "--ground-elevation-m", "0", "-o", str(tmp_path / "w")
    )
    assert code == 2 and "--overwrite" in err
    assert (tmp_path / "w" / "pairs.txt").read_bytes() == before


def test_odm_project_has_what_odm_reads(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    gcp = _gcp_csv(tmp_path / "gcp.csv", frames, images)
    code, _, err = _run(
        "handoff",
        str(images),
        "--to",
        "odm",
        "--ground-elevation-m",
        "0",
        "--gcp",
        str(gcp),
        "-o",
        str(tmp_path / "odm"),
    )
    assert code == 0, err
    work = tmp_path / "odm"
    assert sorted(p.name for p in (work / "images").iterdir()) == sorted(f[0] for f in frames)
    assert (work / "images" / frames[0][0]).read_bytes() == (images / frames[0][0]).read_bytes()
    geo = (work / "geo.txt").read_text().splitlines()
    assert CRS.from_user_input(geo[0]).to_epsg() == 4326
    by_name = {line.split()[0]: [float(v) for v in line.split()[1:]] for line in geo[1:]}
    assert len(by_name) == len(frames)
    for name, *_ in frames:
        with open(images / name, "rb") as handle:
            tags = exifread.process_file(handle, details=False)
        d, m, s = (float(v.num) / float(v.den) for v in tags["GPS GPSLatitude"].values)
        assert by_name[name][1] == pytest.approx(d + m / 60 + s / 3600, abs=1e-7)
        assert by_name[name][2] == pytest.approx(HEIGHT_M, abs=1e-3)
        assert by_name[name][6:8] == [1.5, 3.0]
    gcp_lines = (work / "gcp_list.txt").read_text().splitlines()
    assert CRS.from_user_input(gcp_lines[0]).to_epsg() == 4326
    assert len(gcp_lines) == 1 + 6
    options = {o["name"]: o["value"] for o in json.loads((work / "options.json").read_text())}
    # No --gps-accuracy: ODM would force that one figure on every image over geo.txt's own.
    assert "gps-accuracy" not in options
    assert options["camera-lens"] == "brown"
    # matcher-neighbors: the median number of frames whose nadir footprint (FOOT_X_M x FOOT_Y_M
    # rectangles over flat ground) overlaps a frame's by 5 % or more, counted here from the grid.
    partners = [
        sum(
            1
            for other in frames
            if other is not f
            and max(0.0, FOOT_X_M - abs(f[1] - other[1])) * max(0.0, FOOT_Y_M - abs(f[2] - other[2]))
            >= 0.05 * FOOT_X_M * FOOT_Y_M
        )
        for f in frames
    ]
    assert options["matcher-neighbors"] == math.ceil(statistics.median(partners))
    assert options["matcher-neighbors"] < len(frames) - 1
    args = (work / "odm_args.txt").read_text()
    assert "--gps-accuracy" not in args and "--gcp gcp_list.txt" in args


def test_odm_leaves_matcher_neighbors_to_odm_when_every_frame_overlaps_every_other(
    tmp_path: Path,
) -> None:
    grid(tmp_path / "img", lines=1, per_line=4, dx_m=110.0, dy_m=20.0)
    code, _, err = _run(
        "handoff",
        str(tmp_path / "img"),
        "--to",
        "odm",
        "--ground-elevation-m",
        "0",
        "-o",
        str(tmp_path / "o"),
    )
    assert code == 0, err
    options = {o["name"] for o in json.loads((tmp_path / "o" / "options.json").read_text())}
    assert options == {"camera-lens"}  # 3 neighbours of 4 frames would be exhaustive matching


@pytest.mark.parametrize("engine", ["metashape", "pix4d"])
def test_reference_files_with_a_readme(tmp_path: Path, block, engine: str) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    gcp = _gcp_csv(tmp_path / "gcp.csv", frames, images)
    code, _, err = _run(
        "handoff",
        str(images),
        "--to",
        engine,
        "--ground-elevation-m",
        "0",
        "--gcp",
        str(gcp),
        "-o",
        str(tmp_path / "r"),
    )
    assert code == 0, err
    readme = (tmp_path / "r" / "README.txt").read_text()
    listed = [p.name for p in (tmp_path / "r").iterdir() if p.suffix == ".csv"]
    assert len(listed) == 3
    for name in listed:
        assert name in readme  # every file says which menu imports it
    cams = next(p for p in listed if p.startswith("cameras"))
    rows = (tmp_path / "r" / cams).read_text().splitlines()
    assert len(rows) == len(frames)
    assert all(math.isfinite(float(v)) for v in rows[0].split(",")[1:])


def test_bad_input_exits_2_with_the_fix(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    # A ground above the cameras: refused with the figures, nothing written.
    code, _, err = _run(
        "handoff", str(images), "--to", "colmap", "--ground-elevation-m", "500", "-o", str(tmp_path / "a")
    )
    assert code == 2 and "check the ground elevation" in err and not (tmp_path / "a").exists()
    code, _, err = _run(
        "handoff", str(images), "--to", "odm", "--run", "--ground-elevation-m", "0", "-o", str(tmp_path / "b")
    )
    assert code == 2 and "--run" in err
    bad = tmp_path / "bad.txt"
    bad.write_text("NOT A CRS\n1 2 0 10 10 F000.jpg g1\n")
    code, _, err = _run(
        "handoff",
        str(images),
        "--to",
        "odm",
        "--ground-elevation-m",
        "0",
        "--gcp",
        str(bad),
        "-o",
        str(tmp_path / "c"),
    )
    assert code == 2 and "not a coordinate reference system" in err
    code, _, err = _run(
        "handoff",
        str(images),
        "--to",
        "colmap",
        "--ground-elevation-m",
        "0",
        "--check-points",
        "2",
        "-o",
        str(tmp_path / "d"),
    )
    assert code == 2 and "--gcp" in err
    gcp = _gcp_csv(tmp_path / "gcp.csv", frames, images)
    code, _, err = _run(
        "handoff",
        str(images),
        "--to",
        "colmap",
        "--ground-elevation-m",
        "0",
        "--gcp",
        str(gcp),
        "--check-points",
        "1",
        "-o",
        str(tmp_path / "e"),
    )
    assert code == 2 and "usable control point" in err
    assert not any((tmp_path / n).exists() for n in "abcde")
    assert "Traceback" not in err


def test_a_given_camera_sets_the_intrinsics(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    """--camera FILE.toml: the frames (320 px wide) are scaled copies of a 640 px camera with a
    6.4 mm sensor and an 8 mm lens, so the focal length is 8 mm / (6.4 mm / 320 px) = 400 px
    in the COLMAP database, whatever the frames' own EXIF says (4 mm, 0.02 mm pixels: 200 px)."""
    import pycolmap

    images, _ = block
    camera = tmp_path / "camera.toml"
    camera.write_text(
        "[camera]\nsensor_width_mm = 6.4\nsensor_height_mm = 4.8\nimage_width_px = 640\n"
        "image_height_px = 480\nfocal_length_mm = 8\n"
    )
    args = ["handoff", str(images), "--to", "colmap", "--ground-elevation-m", "0"]
    code, _, err = _run(*args, "--camera", str(camera), "-o", str(tmp_path / "given"))
    assert code == 0, err
    code, _, err = _run(*args, "-o", str(tmp_path / "exif"))
    assert code == 0, err

    def focal_px(work: Path) -> list[float]:
        database = pycolmap.Database.open(str(work / "database.db"))
        try:
            return [float(c.params[0]) for c in database.read_all_cameras()]
        finally:
            database.close()

    assert focal_px(tmp_path / "given") == [pytest.approx(400.0)]
    assert focal_px(tmp_path / "exif") == [pytest.approx(200.0)]


def test_frames_with_no_focal_length_ask_for_the_camera(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    """Tiny frames whose EXIF gives no focal length: no traceback and no nonsense camera, but
    exit 2 naming --camera; with --camera the project is written."""
    import pyexiv2

    images, _ = block
    for path in images.iterdir():
        with pyexiv2.Image(str(path)) as image:
            image.modify_exif(
                {
                    "Exif.Photo.FocalLength": None,
                    "Exif.Photo.FocalPlaneXResolution": None,
                    "Exif.Photo.FocalPlaneYResolution": None,
                    "Exif.Photo.FocalPlaneResolutionUnit": None,
                }
            )
    args = ["handoff", str(images), "--to", "odm", "--ground-elevation-m", "0"]
    code, _, err = _run(*args, "-o", str(tmp_path / "w"))
    assert code == 2 and "--camera" in err and "Traceback" not in err
    assert not (tmp_path / "w").exists()
    code, _, err = _run(*args, "--camera", "canon-eos-350d-20mm", "-o", str(tmp_path / "w"))
    assert code == 0, err
    assert (tmp_path / "w" / "geo.txt").is_file()


@pytest.mark.parametrize(("mapper", "octave"), [("incremental", "0"), ("global", "-1")])
def test_a_block_that_does_not_reconstruct_exits_1_and_says_so(
    tmp_path: Path, block, mapper: str, octave: str
) -> None:  # type: ignore[no-untyped-def]
    """--run on frames with nothing to match (the grid's plain images): COLMAP ties no two
    frames together; the project and its report are written, and sfap exits 1 saying so."""
    images, _ = block
    work = tmp_path / "work"
    code, out, err = _run("handoff", str(images), "--to", "colmap", "--run", "--ground-elevation-m", "0",
                          "--mapper", mapper, "--max-features", "500", "--sift-first-octave", octave,
                          "-o", str(work))  # fmt: skip
    assert code == 1, out + err
    assert "did NOT reconstruct" in out + err
    report = json.loads((work / "report.json").read_text())
    assert report["quicklook"]["reconstructs"] is False
    quick = report["quicklook"]
    assert (quick["mapper"], quick["max_features"], quick["sift_first_octave"]) == (mapper, 500, int(octave))
    assert set(report["quicklook"]["timings_s"]) >= {"features_s", "matching_s", "mapping_s"}


@pytest.mark.parametrize(
    ("engine", "camera_file"), [("metashape", "cameras_reference.csv"), ("pix4d", "cameras_pix4d.csv")]
)
def test_no_position_writes_no_camera_file_and_exits_1(tmp_path: Path, engine: str, camera_file: str) -> None:
    grid(tmp_path / "img", lines=1, per_line=3, dx_m=110.0, dy_m=45.0, positioned=False)
    code, out, err = _run("handoff", str(tmp_path / "img"), "--to", engine, "-o", str(tmp_path / "r"))
    assert code == 1, out + err
    assert not (tmp_path / "r" / camera_file).exists()
    assert "FAIL: no image has a position" in out and "written: README.txt" in out
    assert f"{camera_file} is not written" in (tmp_path / "r" / "README.txt").read_text()


# Pix4D's documented import formats (support.pix4d.com), quoted:
# "Image geolocation and orientation import format - PIX4Dmatic" (article 360056389172): "It contains
# seven or nine columns per line and uses commas "," as column separators. Note: The .csv or .txt file
# should not contain a header." ... "imagename, coordinate1* [decimal degrees], coordinate2* [decimal
# degrees], z [meter], yaw [decimal degrees], pitch [decimal degrees], roll [decimal degrees], Accuracy
# Horz [meter], Accuracy Vert [meter]" ... "The order of coordinates in the input file needs to follow
# the order of axes in the coordinate system definition".
PIX4D_GEOLOCATION = ["imagename", "coordinate1", "coordinate2", "z", "yaw", "pitch", "roll", "Accuracy Horz",
                     "Accuracy Vert"]  # fmt: skip
# "Tie points (GCPs, CPs) import format - PIX4Dmatic" (article 360038397752): "Each line contains either
# four or six columns, separated by commas" ... "label, coordinate1* [decimal degrees], coordinate2*
# [decimal degrees], z [meter]" (or with "Accuracy Horz [meter], Accuracy Vert [meter]").
PIX4D_GCPS = ["label", "coordinate1", "coordinate2", "z"]
# "How to import and export Tie Points marks - PIX4Dmatic" (article 360035474951): "Image name, Tie Point
# name, image coordinate x, image coordinate y, accuracy (in pixels)".
PIX4D_MARKS = ["Image name", "Tie Point name", "image coordinate x", "image coordinate y", "accuracy"]


@pytest.mark.parametrize("alt_m", [12.5, 0.0], ids=["heights known", "heights unknown"])
def test_pix4d_files_follow_the_documented_columns(tmp_path: Path, block, alt_m: float) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    gcp = _gcp_csv(tmp_path / "gcp.csv", frames, images, alt_m=alt_m)
    code, out, err = _run(
        "handoff", str(images), "--to", "pix4d", "--gcp", str(gcp), "-o", str(tmp_path / "r")
    )
    assert code == 0, out + err
    axes = [a.abbrev.lower() for a in CRS.from_epsg(4326).axis_info]  # the CRS's own axis order
    assert axes == ["lat", "lon"]
    rows = [line.split(",") for line in (tmp_path / "r" / "cameras_pix4d.csv").read_text().splitlines()]
    assert len(rows) == len(frames)  # no header line
    by_name = {r[0]: r for r in rows}
    for name, *_ in frames:
        row = dict(zip(PIX4D_GEOLOCATION, by_name[name], strict=True))
        with open(images / name, "rb") as handle:
            tags = exifread.process_file(handle, details=False)
        d, m, s = (float(v.num) / float(v.den) for v in tags["GPS GPSLatitude"].values)
        assert float(row["coordinate1"]) == pytest.approx(d + m / 60 + s / 3600, abs=1e-7)  # latitude first
        assert float(row["z"]) == pytest.approx(HEIGHT_M, abs=1e-3)
        assert [float(row[k]) for k in ("yaw", "pitch", "roll")] == [0.0, 0.0, 0.0]
        assert (float(row["Accuracy Horz"]), float(row["Accuracy Vert"])) == (1.5, 3.0)  # the tags'
    gcps = [line.split(",") for line in (tmp_path / "r" / "gcps_pix4d.csv").read_text().splitlines()]
    assert [g[0] for g in gcps] == ["g0", "g1", "g2"]  # no header line
    for k, g in enumerate(gcps):
        row = dict(zip(PIX4D_GCPS, g, strict=True))
        assert float(row["coordinate1"]) == pytest.approx(float(f"45.00{k}1")) and float(
            row["coordinate2"]
        ) == pytest.approx(float(f"7.00{k}1"))
        assert row["z"] == ("" if alt_m == 0.0 else f"{alt_m + k:.3f}")  # unknown heights: left empty
    marks = [line.split(",") for line in (tmp_path / "r" / "gcp_image_marks.csv").read_text().splitlines()]
    assert len(marks) == 6
    for m in marks:
        row = dict(zip(PIX4D_MARKS, m, strict=True))
        assert row["Image name"] in {f[0] for f in frames} and row["Tie Point name"] in {"g0", "g1", "g2"}
        assert float(row["accuracy"]) > 0
    readme = (tmp_path / "r" / "README.txt").read_text()
    assert ("unknown height" in readme) == (alt_m == 0.0)


def test_metashape_markers_leave_unknown_heights_empty(tmp_path: Path, block) -> None:  # type: ignore[no-untyped-def]
    images, frames = block
    gcp = _gcp_csv(tmp_path / "gcp.csv", frames, images, alt_m=0.0)
    code, out, err = _run(
        "handoff", str(images), "--to", "metashape", "--gcp", str(gcp), "-o", str(tmp_path / "r")
    )
    assert code == 0, out + err
    lines = (tmp_path / "r" / "markers_reference.csv").read_text().splitlines()
    assert lines[0] == "label,longitude,latitude,altitude"  # no invented accuracy column
    assert [line.split(",")[3] for line in lines[1:]] == ["", "", ""]
    assert "unknown height" in (tmp_path / "r" / "README.txt").read_text()
