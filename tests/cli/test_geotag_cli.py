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


def _csv_track(path: Path, log: FlightLog, shift_s: float = 0.0, *, attitude: bool = False) -> Path:
    """The tlog's positions as an exiftool CSV track (the layout `exiftool -geotag` reads), with
    the vehicle's attitude interpolated onto them when ``attitude``."""
    positions = log.positions
    assert positions is not None and positions.alt_amsl_m is not None
    lines = ["GPSDateTime,GPSLatitude,GPSLongitude,GPSAltitude"]
    rpy: list[np.ndarray] = []
    if attitude:
        att = log.attitudes
        assert att is not None
        lines[0] += ",GPSImgDirection,GPSPitch,GPSRoll"
        yaw = np.mod(
            np.interp(positions.time_utc_s, att.time_utc_s, np.unwrap(att.yaw_deg, period=360.0)), 360
        )
        rpy = [yaw] + [
            np.interp(positions.time_utc_s, att.time_utc_s, c) for c in (att.pitch_deg, att.roll_deg)
        ]
    for k, (t, lat, lon, alt) in enumerate(
        zip(positions.time_utc_s, positions.lat_deg, positions.lon_deg, positions.alt_amsl_m, strict=True)
    ):
        if abs(lat) < 1.0 and abs(lon) < 1.0:
            continue  # the simulator's "0, 0" before its GPS fix
        moment = datetime.fromtimestamp(float(t) + shift_s, tz=UTC)
        stamp = moment.strftime("%Y:%m:%d %H:%M:%S.") + f"{moment.microsecond // 1000:03d}Z"
        lines.append(f"{stamp},{lat:.8f},{lon:.8f},{alt:.3f}" + "".join(f",{c[k]:.3f}" for c in rpy))
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


def _written_pitch_roll(out: Path) -> np.ndarray:
    tags = [exif.read_tags(p) for p in sorted(out.glob("*.JPG"))]
    assert tags and all(t.camera_pitch_deg is not None and t.camera_roll_deg is not None for t in tags)
    return np.array([[t.camera_pitch_deg, t.camera_roll_deg] for t in tags], dtype=float)


def test_camera_mount_follows_the_log_unless_given(
    tmp_path: Path, sitl_card: Path, sitl_log: FlightLog
) -> None:
    """Issue 24: without gimbal angles, the default camera mount is what the log says the vehicle
    is: the SITL plane's tlog says a fixed wing, so its body-fixed camera takes the vehicle's
    pitch and roll (it fires while banking); --camera-mount gimbal overrides the log; a CSV track
    says nothing, so a gimbal is assumed, and the output says so each time."""
    code, _, stderr = _run("geotag", sitl_card, "--log", SITL_TLOG, "-o", tmp_path / "auto")
    assert code == 0, stderr
    assert (
        "the vehicle's, the camera fixed to the airframe" in stderr and "the log says a fixed wing" in stderr
    )
    assert np.abs(_written_pitch_roll(tmp_path / "auto")).max() > 5.0
    code, _, stderr = _run(
        "geotag", sitl_card, "--log", SITL_TLOG, "-o", tmp_path / "gimbal", "--camera-mount", "gimbal"
    )
    assert code == 0, stderr
    assert "stabilised gimbal" in stderr and "; --camera-mount gimbal)" in stderr
    assert np.abs(_written_pitch_roll(tmp_path / "gimbal")).max() == 0.0
    track = _csv_track(tmp_path / "track.csv", sitl_log, attitude=True)
    code, _, stderr = _run(
        "geotag", sitl_card, "--log", track, "-o", tmp_path / "csv", "--offset-s", str(OFFSET_S)
    )
    assert "the log does not say what the vehicle is: a gimbal assumed" in stderr, stderr
    assert np.abs(_written_pitch_roll(tmp_path / "csv")).max() == 0.0


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
    # The frames were being copied into a staging folder meanwhile: it is gone, with them.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["card"]


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


# ------------------------------------------------ subsets of a card, sync points, early checks


def _feedback_positions() -> dict[int, tuple[float, float]]:
    """img_idx -> (lat, lon) of every CAMERA_FEEDBACK in the tlog, read with pymavlink."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(SITL_TLOG), robust_parsing=True)
    out: dict[int, tuple[float, float]] = {}
    try:
        while (m := conn.recv_match(type="CAMERA_FEEDBACK")) is not None:
            out.setdefault(int(m.img_idx), (m.lat * 1e-7, m.lng * 1e-7))
    finally:
        conn.close()
    return out


def _metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    north = (a[0] - b[0]) * 111_195.0
    east = (a[1] - b[1]) * 111_195.0 * math.cos(math.radians(a[0]))
    return math.hypot(north, east)


@pytest.fixture
def subset_card(tmp_path: Path, sitl_log: FlightLog) -> tuple[Path, list[int]]:
    """One DCIM subfolder of the card: 15 frames of the 70 events (22 to 36), in 101CANON."""
    events = sitl_log.events
    assert events is not None
    jitter = np.random.default_rng(8).normal(0, 0.03, len(events))
    chosen = list(range(22, 37))
    for k, j in enumerate(chosen):
        write_frame(
            tmp_path / "DCIM" / "101CANON" / f"IMG_{k + 1:04d}.JPG",
            float(events.time_utc_s[j] + OFFSET_S + jitter[j]),
        )
    return tmp_path / "DCIM", chosen


def test_a_subset_of_a_card_is_refused_until_the_offset_is_confirmed(
    tmp_path: Path, subset_card: tuple[Path, list[int]], sitl_log: FlightLog
) -> None:
    """The SITL plane fires every 2.2 s all flight long: 15 frames fit many stretches of it.
    Nothing is written, the competing offsets are named, exit 1; then each way the crew can
    settle it places every frame on its own event (positions from pymavlink's CAMERA_FEEDBACK)."""
    card, chosen = subset_card
    out = tmp_path / "out"
    code, _, stderr = _run("geotag", card, "--log", SITL_TLOG, "-o", out)
    assert code == 1, stderr
    assert "ambiguous" in stderr and "other offset(s) fit nearly as well" in stderr
    assert "--offset-s" in stderr and "--sync" in stderr
    assert not out.exists()

    truth = _feedback_positions()
    events = sitl_log.events
    assert events is not None
    first = float(events.time_utc_s[chosen[0]])
    first_pos = truth[int(events.seq[chosen[0]])]
    settle = {
        "offset": ["--offset-s", str(OFFSET_S)],
        "sync_time": [
            "--sync",
            f"101CANON/IMG_0001.JPG={datetime.fromtimestamp(first + 0.4, tz=UTC).isoformat()}",
        ],
        "sync_position": ["--sync-position", f"IMG_0001.JPG={first_pos[0] + 3e-5:.7f},{first_pos[1]:.7f}"],
    }
    for how, args in settle.items():
        target = tmp_path / f"out_{how}"
        code, stdout, stderr = _run("geotag", card, "--log", SITL_TLOG, "-o", target, "--json", *args)
        assert code == 0, (how, stderr)
        report = json.loads(stdout)
        assert report["summary"]["offset_source"] == ("given" if how == "offset" else "sync")
        frames = sorted(report["frames"], key=lambda f: f["name"])
        assert [f["status"] for f in frames] == ["matched"] * len(chosen)
        for k, frame in enumerate(frames):
            expected = truth[int(events.seq[chosen[k]])]
            assert _metres((frame["lat_deg"], frame["lon_deg"]), expected) < 1.0, (how, k)


def test_sync_points_bad_input_exit_2(tmp_path: Path, subset_card: tuple[Path, list[int]]) -> None:
    card, _ = subset_card
    out = tmp_path / "out"
    cases = [
        (["--sync", "IMG_0001.JPG"], "FRAME=TIME"),
        (["--sync", "IMG_0001.JPG=yesterday"], "not an ISO 8601 time"),
        (["--sync-position", "IMG_0001.JPG=42.0"], "FRAME=LAT,LON"),
        (["--sync-position", "IMG_0001.JPG=142.0,-93"], "not a latitude"),
        (["--sync", "NOPE.JPG=2026-11-22T10:00:00Z"], "NOPE.JPG is not an image"),
        (["--sync", "IMG_0001.JPG=2026-11-22T10:00:00Z", "--offset-s", "3"], "either --offset-s or sync"),
        (["--offset-s", "nan"], "not a finite number"),
        (["--sync-position", "IMG_0001.JPG=10.0,10.0"], "not on the flight"),
    ]
    for args, message in cases:
        code, _, stderr = _run("geotag", card, "--log", SITL_TLOG, "-o", out, *args)
        assert code == 2, (args, stderr)
        assert message in stderr, (args, stderr)
        assert "Traceback" not in stderr
    assert not out.exists()


def test_folder_and_options_are_checked_before_the_log_is_read(tmp_path: Path) -> None:
    """An empty folder (or a bad option) is refused at once: the log, here not even a log, is
    not read first."""
    garbage = tmp_path / "flight.tlog"
    garbage.write_bytes(b"this is not a flight log" * 1000)
    (tmp_path / "DCIM" / "100CANON").mkdir(parents=True)
    code, _, stderr = _run("geotag", tmp_path / "DCIM", "--log", garbage, "-o", tmp_path / "out")
    assert code == 2 and "no JPEG images" in stderr and "flight.tlog" not in stderr
    write_frame(tmp_path / "DCIM" / "100CANON" / "A.JPG", 1.7e9)
    for args, message in ((["--tolerance-s", "0"], "--tolerance-s"), (["--max-gap-s", "-1"], "--max-gap-s")):
        code, _, stderr = _run("geotag", tmp_path / "DCIM", "--log", garbage, "-o", tmp_path / "out", *args)
        assert code == 2 and message in stderr and "flight.tlog" not in stderr, stderr
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "old.txt").write_text("keep")
    code, _, stderr = _run("geotag", tmp_path / "DCIM", "--log", garbage, "-o", tmp_path / "out")
    assert code == 2 and "--overwrite" in stderr and "flight.tlog" not in stderr


def test_by_time_says_what_a_wrong_offset_costs_and_takes_a_sync_position(
    tmp_path: Path, sitl_log: FlightLog
) -> None:
    """A CSV track has no camera events: frames are placed by capture time. The warning gives
    the metres per second of clock error at the flight's ground speed (checked against the
    track's own median speed); a sync position finds the offset."""
    track = _csv_track(tmp_path / "track.csv", sitl_log)
    positions = sitl_log.positions
    events = sitl_log.events
    assert positions is not None and events is not None
    for k, j in enumerate(range(20, 30)):
        write_frame(tmp_path / "card" / f"F{k}.JPG", float(events.time_utc_s[j] + OFFSET_S))
    code, _, stderr = _run("geotag", tmp_path / "card", "--log", track, "-o", tmp_path / "a", "--dry-run")
    assert "ASSUMED to be 0 s" in stderr
    # The speed, from the track's positions during those frames, written out here.
    lat, lon, t = positions.lat_deg, positions.lon_deg, positions.time_utc_s
    inside = (t > events.time_utc_s[20] - 5) & (t < events.time_utc_s[29] + 5)
    steps = [
        _metres((lat[i], lon[i]), (lat[i + 1], lon[i + 1])) / (t[i + 1] - t[i])
        for i in np.flatnonzero(inside)[:-1]
    ]
    speed = float(np.median(steps))
    code, stdout, stderr = _run(
        "geotag",
        tmp_path / "card",
        "--log",
        track,
        "-o",
        tmp_path / "b",
        "--dry-run",
        "--offset-s",
        str(OFFSET_S),
    )
    assert code == 0, stderr
    stated = float(stderr.split("every second it is wrong moves each frame about ")[1].split(" m")[0])
    assert stated == pytest.approx(speed, rel=0.1)
    truth = _feedback_positions()
    known = truth[int(events.seq[20])]
    code, stdout, stderr = _run(
        "geotag",
        tmp_path / "card",
        "--log",
        track,
        "-o",
        tmp_path / "c",
        "--json",
        "--sync-position",
        f"F0.JPG={known[0]:.7f},{known[1]:.7f}",
    )
    assert code == 0, stderr
    report = json.loads(stdout)
    assert report["summary"]["offset_source"] == "sync"
    assert report["summary"]["offset_s"] == pytest.approx(OFFSET_S, abs=0.3)
    for frame in report["frames"]:
        k = int(frame["name"][1:-4])
        assert _metres((frame["lat_deg"], frame["lon_deg"]), truth[int(events.seq[20 + k])]) < 5.0


def test_each_warning_is_printed_once(tmp_path: Path, sitl_log: FlightLog) -> None:
    """The real command (its own process, its own logging set-up): a track with an empty
    altitude cell (the reader warns, and the run carries it), frames placed by time (the run
    warns), and a frame cut short before its end marker (its writer warns): each warning
    appears on stderr exactly once."""
    import subprocess
    import sys

    track = _csv_track(tmp_path / "track.csv", sitl_log)
    lines = track.read_text().splitlines()
    lines[3] = lines[3].rsplit(",", 1)[0] + ","
    track.write_text("\n".join(lines) + "\n")
    events = sitl_log.events
    assert events is not None
    for k, j in enumerate(range(20, 26)):
        write_frame(tmp_path / "card" / f"F{k}.JPG", float(events.time_utc_s[j]))
    cut = tmp_path / "card" / "F2.JPG"
    cut.write_bytes(cut.read_bytes()[:-2])
    command = ["geotag", str(tmp_path / "card"), "--log", str(track), "-o", str(tmp_path / "out")]
    done = subprocess.run(
        [sys.executable, "-m", "sfap", *command, "--offset-s", "0", "--no-progress"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    warned = [line for line in done.stderr.splitlines() if "warning" in line.lower()]
    said = ["column GPSAltitude is empty at line 4", "frames are placed by their capture time", "F2.JPG"]
    for words in said:
        assert sum(words in line for line in warned) == 1, (words, done.stderr)
    assert len(warned) == len(said), done.stderr


def test_warnings_held_and_not_shown_are_printed_at_the_end(capsys: pytest.CaptureFixture[str]) -> None:
    """sfap.common.warnings_once: what the command showed is not printed again, what it did not
    show is printed once when it ends (an error included); other loggers pass through."""
    import logging
    import sys

    from sfap.common import warnings_once

    handler = logging.StreamHandler(sys.stderr)  # as sfap's logging set-up makes it
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        with pytest.raises(RuntimeError), warnings_once("acquisition") as handled:
            logging.getLogger("acquisition.exif").warning("shown by the command")
            logging.getLogger("acquisition").warning("only %s", "logged")
            logging.getLogger("acquisition").warning("only %s", "logged")
            logging.getLogger("acquisitions").warning("another package")
            logging.getLogger("planner").warning("not held")
            handled.add("shown by the command")
            raise RuntimeError("the run failed")
    finally:
        root.removeHandler(handler)
    assert capsys.readouterr().err.splitlines() == ["another package", "not held", "warning: only logged"]
