"""`sfap geotag` through the real click group: the real ArduPilot tlog, CSV tracks, exit codes,
--json, --dry-run, --in-place with a backup, and the messages for bad input."""

from __future__ import annotations

import io
import json
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyexiv2
import pytest
from click.testing import CliRunner
from PIL import Image
from shared_data import SHARED_DATA

from acquisition import exif
from acquisition.telemetry import read_log
from acquisition.telemetry.model import FlightLog
from sfap.cli import cli

SITL_TLOG = SHARED_DATA / "ardupilot_sitl_plane" / "flight.tlog"
SITL_BIN = SHARED_DATA / "ardupilot_sitl_plane" / "flight.BIN"  # the same flight's DataFlash
OFFSET_S = -3600.0 + 12.75  # a camera set to the wrong time zone, and 12.75 s off
DROPPED = (5, 6, 50)


def _run(*args: str | Path) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def _jpeg_bytes() -> bytes:
    pixels = np.random.default_rng(0).integers(0, 256, size=(24, 32, 3), dtype=np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="JPEG", quality=80)
    return buffer.getvalue()


def write_frame(path: Path, capture_s: float | None) -> Path:
    image = pyexiv2.ImageData(_jpeg_bytes())
    if capture_s is not None:
        whole = math.floor(capture_s)
        millis = min(999, round((capture_s - whole) * 1000))
        stamp = datetime.fromtimestamp(whole, tz=UTC).strftime("%Y:%m:%d %H:%M:%S")
        image.modify_exif(
            {"Exif.Photo.DateTimeOriginal": stamp, "Exif.Photo.SubSecTimeOriginal": f"{millis:03d}"}
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(image.get_bytes())
    image.close()
    return path


@pytest.fixture(scope="module")
def sitl_log() -> FlightLog:
    return read_log(SITL_TLOG)


@pytest.fixture
def sitl_card(tmp_path: Path, sitl_log: FlightLog) -> Path:
    """One frame per real camera event (offset, 40 ms jitter), 3 dropped, 1 spurious."""
    events = sitl_log.events
    assert events is not None
    times = events.time_utc_s + OFFSET_S + np.random.default_rng(3).normal(0, 0.04, len(events))
    times = np.delete(times, DROPPED)
    times = np.sort(np.append(times, events.time_utc_s[30] + OFFSET_S + 1.2))
    for k, t in enumerate(times):
        write_frame(tmp_path / "card" / f"IMG_{k:04d}.JPG", float(t))
    return tmp_path / "card"


def _csv_track(path: Path, log: FlightLog, shift_s: float = 0.0) -> Path:
    """The tlog's positions as an exiftool CSV track (the layout `exiftool -geotag` reads)."""
    positions = log.positions
    assert positions is not None and positions.alt_amsl_m is not None
    lines = ["GPSDateTime,GPSLatitude,GPSLongitude,GPSAltitude"]
    for t, lat, lon, alt in zip(
        positions.time_utc_s,
        positions.lat_deg,
        positions.lon_deg,
        positions.alt_amsl_m,
        strict=True,
    ):
        if abs(lat) < 1.0 and abs(lon) < 1.0:
            continue  # the simulator's "0, 0" before its GPS fix
        moment = datetime.fromtimestamp(float(t) + shift_s, tz=UTC)
        stamp = moment.strftime("%Y:%m:%d %H:%M:%S.") + f"{moment.microsecond // 1000:03d}Z"
        lines.append(f"{stamp},{lat:.8f},{lon:.8f},{alt:.3f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_geotag_real_tlog_names_dropped_and_extra(
    tmp_path: Path, sitl_card: Path, sitl_log: FlightLog
) -> None:
    out = tmp_path / "out"
    code, stdout, stderr = _run("geotag", sitl_card, "--log", SITL_TLOG, "-o", out)
    assert code == 0, stderr
    events = sitl_log.events
    assert events is not None
    seqs = ", ".join(str(int(events.seq[j])) for j in DROPPED)
    assert f"3 events without a frame: seq {seqs}" in stdout
    assert "extra frames" in stdout and "1 without an event: IMG_" in stdout
    assert "camera clock offset  -3587.2" in stdout
    tagged = sorted(p.name for p in out.glob("*.JPG"))
    assert tagged == sorted(p.name for p in sitl_card.iterdir())
    first = exif.read_tags(out / tagged[0])
    assert first.gps_lat_deg is not None and first.camera_yaw_deg is not None
    assert exif.compressed_image_data(out / tagged[0]) == exif.compressed_image_data(sitl_card / tagged[0])
    assert exif.read_tags(sitl_card / tagged[0]).gps_lat_deg is None  # originals untouched
    assert (out / "geo.txt").read_text().startswith("EPSG:4326\n")


def test_json_output_and_untagged_exit_1(tmp_path: Path, sitl_card: Path) -> None:
    write_frame(sitl_card / "NOTIME.JPG", None)
    (sitl_card / "BROKEN.JPG").write_bytes(b"\xff\xd8\xff\xe1broken")
    code, stdout, _ = _run("geotag", sitl_card, "--log", SITL_BIN, "-o", tmp_path / "out", "--json")
    assert code == 1
    report = json.loads(stdout)
    summary = report["summary"]
    assert {u["name"]: u["status"] for u in summary["untagged"]} == {
        "NOTIME.JPG": "no_capture_time",
        "BROKEN.JPG": "unreadable",
    }
    assert [e["index"] for e in summary["unmatched_events"]] == list(DROPPED)
    assert len(summary["extra_frames"]) == 1
    assert summary["offset_s"] == pytest.approx(OFFSET_S, abs=0.03)
    matched = [f for f in report["frames"] if f["status"] == "matched"]
    assert len(matched) == 70 - len(DROPPED)
    assert all(abs(f["time_residual_s"]) < 0.2 and f["interpolation_gap_s"] < 1.0 for f in matched)
    assert not (tmp_path / "out" / "NOTIME.JPG").exists() and not (tmp_path / "out" / "BROKEN.JPG").exists()


def test_untagged_frames_are_listed_in_text(tmp_path: Path, sitl_log: FlightLog) -> None:
    track = _csv_track(tmp_path / "track.csv", sitl_log)
    positions = sitl_log.positions
    assert positions is not None
    t_mid = float(np.median(positions.time_utc_s))
    write_frame(tmp_path / "card" / "A.JPG", t_mid)
    write_frame(tmp_path / "card" / "B.JPG", t_mid + 86_400.0)  # a frame from the next day
    code, stdout, _ = _run(
        "geotag", tmp_path / "card", "--log", track, "-o", tmp_path / "out", "--offset-s", "0"
    )
    assert code == 1
    assert "untagged frames (1)" in stdout and "B.JPG" in stdout and "after the log" in stdout
    assert (tmp_path / "out" / "A.JPG").exists() and not (tmp_path / "out" / "B.JPG").exists()


def test_log_from_another_day_exit_1(tmp_path: Path, sitl_log: FlightLog, sitl_card: Path) -> None:
    track = _csv_track(tmp_path / "track.csv", sitl_log, shift_s=-86_400.0)
    code, stdout, stderr = _run(
        "geotag", sitl_card, "--log", track, "-o", tmp_path / "out", "--offset-s", str(OFFSET_S)
    )
    assert code == 1
    assert "another flight or day" in stderr
    assert stdout.count("after the log") == len(list(sitl_card.iterdir()))


def test_irreconcilable_counts_exit_1(tmp_path: Path, sitl_log: FlightLog) -> None:
    events = sitl_log.events
    assert events is not None
    rng = np.random.default_rng(1)
    for k, t in enumerate(np.sort(rng.uniform(0, 600, 40)) + float(events.time_utc_s[0])):
        write_frame(tmp_path / "card" / f"X{k:03d}.JPG", float(t))
    code, _, stderr = _run("geotag", tmp_path / "card", "--log", SITL_BIN, "-o", tmp_path / "out")
    assert code == 1
    assert "cannot be reconciled: 40 frames, 70 events" in stderr
    assert not (tmp_path / "out").exists()


def test_dry_run_in_place_and_overwrite(tmp_path: Path, sitl_log: FlightLog) -> None:
    track = _csv_track(tmp_path / "track.csv", sitl_log)
    positions = sitl_log.positions
    assert positions is not None
    t0 = float(np.median(positions.time_utc_s))
    for k in range(5):
        write_frame(tmp_path / "card" / f"F{k}.JPG", t0 + 2.0 * k)
    originals = {p.name: p.read_bytes() for p in (tmp_path / "card").iterdir()}
    out = tmp_path / "out"
    code, stdout, _ = _run(
        "geotag", tmp_path / "card", "--log", track, "-o", out, "--dry-run", "--offset-s", "0"
    )
    assert code == 0 and "dry run: nothing written" in stdout and not out.exists()
    code, _, stderr = _run("geotag", tmp_path / "card", "--log", track, "-o", out, "--in-place")
    assert code == 2 and "--backup-dir" in stderr
    code, _, stderr = _run(
        "geotag",
        tmp_path / "card",
        "--log",
        track,
        "-o",
        out,
        "--in-place",
        "--backup-dir",
        tmp_path / "bak",
    )
    assert code == 0, stderr
    for name, data in originals.items():
        assert (tmp_path / "bak" / name).read_bytes() == data
        assert exif.read_tags(tmp_path / "card" / name).gps_lat_deg is not None
    code, _, stderr = _run("geotag", tmp_path / "card", "--log", track, "-o", out, "--offset-s", "0")
    assert code == 2 and "--overwrite" in stderr
    code, _, stderr = _run(
        "geotag", tmp_path / "card", "--log", track, "-o", out, "--offset-s", "0", "--overwrite"
    )
    assert code == 0, stderr


def test_bad_log_and_help(tmp_path: Path) -> None:
    write_frame(tmp_path / "card" / "A.JPG", 1.7e9)
    garbage = tmp_path / "flight.tlog"
    garbage.write_bytes(b"this is not a flight log")
    code, _, stderr = _run("geotag", tmp_path / "card", "--log", garbage, "-o", tmp_path / "out")
    assert code == 2 and "flight.tlog" in stderr
    code, _, stderr = _run("geotag", tmp_path / "nowhere", "--log", garbage, "-o", tmp_path / "out")
    assert code == 2
    code, stdout, _ = _run("geotag", "--help")
    assert code == 0 and "Example: sfap geotag" in stdout and "--offset-s" in stdout
