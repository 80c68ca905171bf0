"""Issue 24: bad inputs answered with one clear line naming the value and the fix, the README's
exit code (2 bad usage or input, 1 a failed operation), and nothing written."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from survey_frames import write_frame

from sfap.cli import cli

REPO = Path(__file__).resolve().parents[2]
GULLY = REPO / "missions" / "bardenas-gully.toml"


def _files(root: Path) -> set[Path]:
    return {p.relative_to(root) for p in root.rglob("*")}


@pytest.fixture
def gully(tmp_path: Path) -> Path:
    """A copy of the gully spec and its area in tmp_path/spec."""
    folder = tmp_path / "spec"
    folder.mkdir()
    shutil.copy(GULLY, folder / "g.toml")
    shutil.copy(REPO / "missions" / "bardenas-gully.geojson", folder / "bardenas-gully.geojson")
    return folder / "g.toml"


def _area_ring(gully: Path) -> list[list[float]]:
    data = json.loads((gully.parent / "bardenas-gully.geojson").read_text())
    ring: list[list[float]] = data["features"][0]["geometry"]["coordinates"][0]
    return ring


def _refused(args: list[str], code: int, *needles: str) -> str:
    result = CliRunner().invoke(cli, args)
    message = result.output.strip().splitlines()[-1] if result.output.strip() else ""
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in message, message
    return message


def test_a_spec_beginning_with_a_byte_order_mark_is_read(gully: Path, tmp_path: Path) -> None:
    """A mark some editors (Notepad) put first: the plan is the one of the same spec without it."""
    plain = CliRunner().invoke(cli, ["plan", str(gully), "-o", str(tmp_path / "plain"), "--json"])
    gully.write_bytes(b"\xef\xbb\xbf" + gully.read_bytes())
    marked = CliRunner().invoke(cli, ["plan", str(gully), "-o", str(tmp_path / "marked"), "--json"])
    assert plain.exit_code == 0 and marked.exit_code == 0, marked.output
    assert json.loads(marked.stdout)["photo_count"] == json.loads(plain.stdout)["photo_count"] > 0
    assert (tmp_path / "marked" / "mission.plan").read_bytes() == (
        tmp_path / "plain" / "mission.plan"
    ).read_bytes()


def test_a_line_as_the_area_mentions_corridor_width(gully: Path, tmp_path: Path) -> None:
    line = {"type": "LineString", "coordinates": _area_ring(gully)[:3]}
    (gully.parent / "bardenas-gully.geojson").write_text(json.dumps(line))
    _refused(["plan", str(gully), "-o", str(tmp_path / "out")], 2, "corridor_width_m", "Polygon")
    assert not (tmp_path / "out").exists()


def test_a_folder_as_the_area_file_is_named_a_folder(gully: Path, tmp_path: Path) -> None:
    gully.write_text(gully.read_text().replace('"bardenas-gully.geojson"', '"."'))
    _refused(["plan", str(gully), "-o", str(tmp_path / "out")], 2, "is a folder", "GeoJSON or KML")


def test_an_area_written_lat_lon_is_named_with_the_areas_order(gully: Path, tmp_path: Path) -> None:
    swapped = {"type": "Polygon", "coordinates": [[[lat, lon] for lon, lat in _area_ring(gully)]]}
    (gully.parent / "bardenas-gully.geojson").write_text(json.dumps(swapped))
    message = _refused(
        ["plan", str(gully), "-o", str(tmp_path / "out")], 2, "area file's positions must be [lon, lat]"
    )
    assert "swapped" in message and "lon 42.2" in message  # how the area was read
    assert not (tmp_path / "out").exists()


def test_a_height_over_the_limit_without_a_gsd_asks_for_a_lower_height(gully: Path, tmp_path: Path) -> None:
    text = gully.read_text()
    assert "gsd_cm = 2.4" in text
    gully.write_text(text.replace("gsd_cm = 2.4", "altitude_agl_m = 200"))
    message = _refused(
        ["plan", str(gully), "-o", str(tmp_path / "out")],
        2,
        "altitude_agl_m = 200",
        "altitude_agl_m = 120 or lower",
    )
    assert "gsd_cm" not in message


def test_an_output_path_below_a_file_names_the_file(gully: Path, tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    _refused(
        ["plan", str(gully), "-o", str(tmp_path / "afile" / "out")],
        2,
        f"{tmp_path / 'afile'} is a file, not a folder",
        "-o",
    )
    _refused(["gcp-plan", str(gully), "-o", str(tmp_path / "afile" / "g")], 2, "is a file, not a folder")
    assert (tmp_path / "afile").read_text() == "x"


@pytest.fixture
def read_only_dir(tmp_path: Path) -> Iterator[Path]:
    """A folder nothing can be created in: mode 555, and for root (whom modes do not stop) the
    immutable attribute."""
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    immutable = False
    try:
        (folder / "probe").touch()
    except PermissionError:
        pass
    else:
        (folder / "probe").unlink()
        immutable = shutil.which("chattr") is not None and (
            subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0
        )
        if not immutable:
            pytest.skip("cannot make a read-only folder here (root without chattr +i)")
    yield folder
    if immutable:
        subprocess.run(["chattr", "-i", str(folder)], check=True)
    folder.chmod(0o755)


def test_a_read_only_output_folder_is_named_as_given(
    gully: Path, tmp_path: Path, read_only_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    for args in (["plan", str(gully), "-o", "ro/out"], ["gcp-plan", str(gully), "-o", "ro/g"]):
        message = _refused(args, 1, f"cannot write the output folder {args[-1]}: ro is not writable")
        assert ".staging" not in message
    card = tmp_path / "card"
    write_frame(card / "IMG_0001.JPG", 1_700_000_000.0)
    (tmp_path / "flight.tlog").write_bytes(b"")
    message = _refused(
        ["geotag", "card", "--log", "flight.tlog", "-o", "ro/tagged", "--no-progress"],
        1,
        "cannot write the output folder ro/tagged: ro is not writable",
    )
    assert ".staging" not in message
    assert not any(read_only_dir.iterdir())


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "3601"])
def test_max_gap_states_its_range(tmp_path: Path, value: str) -> None:
    card = tmp_path / "card"
    write_frame(card / "IMG_0001.JPG", 1_700_000_000.0)
    (tmp_path / "flight.tlog").write_bytes(b"")
    args = ["geotag", str(card), "--log", str(tmp_path / "flight.tlog"), "-o", str(tmp_path / "out")]
    _refused(
        [*args, "--max-gap-s", value], 2, "--max-gap-s", "above 0 s and at most 3600 s", "(0 < s <= 3600)"
    )
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["sim", "--listen", "tcpin://127.0.0.1:0", "--duration-s", "nan"],
        ["sim", "--listen", "tcpin://127.0.0.1:0", "--latency-s", "nan"],
        ["sim", "--listen", "tcpin://127.0.0.1:0", "--loss-pct", "nan"],
        ["sim", "--listen", "tcpin://127.0.0.1:0", "--speedup", "inf"],
        ["monitor", "--connect", "tcp://127.0.0.1:9", "--heartbeat-timeout-s", "nan", "-o", "m"],
        ["monitor", "--connect", "tcp://127.0.0.1:9", "--reconnect-timeout-s", "nan", "-o", "m"],
    ],
)
def test_a_timeout_or_rate_of_nan_is_refused_by_name(
    args: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """click's FloatRange lets NaN through (every comparison with it is false): a timeout of nan
    would wait forever."""
    monkeypatch.chdir(tmp_path)
    option = next(a for a in args if a.startswith("--") and a not in ("--listen", "--connect"))
    _refused(args, 2, f"'{option}'", "is not a finite number")
    assert not any(tmp_path.iterdir())


def test_what_monitor_and_sim_will_write_is_checked_before_they_start(
    tmp_path: Path, read_only_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Nothing listens on the port: the folder's problem must be found before connecting."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    monitor = ["monitor", "--connect", "tcp://127.0.0.1:9", "--heartbeat-timeout-s", "0.5"]
    _refused([*monitor, "-o", "afile/rec"], 2, "afile is a file, not a folder")
    _refused([*monitor, "-o", "ro/rec"], 1, "cannot write the recording folder ro/rec: ro is not writable")
    sim = ["sim", "--listen", "tcpin://127.0.0.1:0", "--duration-s", "0.1"]
    _refused([*sim, "--frames", "afile/frames"], 2, "frames folder afile/frames: afile is a file")
    _refused([*sim, "--tlog", "ro/sim.tlog"], 1, "cannot write the tlog ro/sim.tlog: ro is not writable")
    assert not any(read_only_dir.iterdir()) and (tmp_path / "afile").read_text() == "x"


def test_geotag_refuses_an_absurd_offset_and_a_backup_folder_below_a_file(
    tmp_path: Path, read_only_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    write_frame(tmp_path / "card" / "IMG_0001.JPG", 1_700_000_000.0)
    (tmp_path / "flight.tlog").write_bytes(b"")
    (tmp_path / "afile").write_text("x")
    args = ["geotag", "card", "--log", "flight.tlog", "--no-progress"]
    _refused([*args, "-o", "out", "--offset-s", "1e12"], 2, "--offset-s", "more than 50 years")
    _refused(
        [*args, "-o", "rep", "--in-place", "--backup-dir", "afile/b"],
        2,
        "backup folder afile/b: afile is a file",
    )
    _refused(
        [*args, "-o", "rep", "--in-place", "--backup-dir", "ro/b"],
        1,
        "cannot write the backup folder ro/b: ro is not writable",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "card", "flight.tlog", "ro"]


# Every number option of the data commands: NaN and infinities parse as floats, and every comparison
# with NaN is false, so a range check downstream would let them through (a cell of nan metres, a
# timeout that never ends). click is the parser here: the option's value is refused by name, exit 2.
# (geotag's --tolerance-s and --max-gap-s state their ranges instead: test_max_gap_states_its_range.)
_NUMBER_OPTIONS = [
    ("check", "--ground-elevation-m"),
    ("check", "--cell-m"),
    ("handoff", "--ground-elevation-m"),
    ("handoff", "--takeoff-elevation-m"),
    ("handoff", "--min-overlap-pct"),
    ("geotag", "--offset-s"),
    ("gcp-plan", "--clearance-m"),
    ("gcp-plan", "--edge-margin-m"),
    ("upload", "--timeout-s"),
    ("upload", "--max-home-distance-m"),
]


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
@pytest.mark.parametrize(("command", "option"), _NUMBER_OPTIONS)
def test_a_number_option_refuses_what_is_not_a_finite_number(
    command: str, option: str, value: str, tmp_path: Path
) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    target = folder if command in ("check", "handoff", "geotag") else folder / "x.toml"
    out = tmp_path / "out"
    output = [] if command == "upload" else ["-o", str(out)]
    result = CliRunner().invoke(cli, [command, str(target), f"{option}={value}", *output])
    assert result.exit_code == 2, result.output
    assert option in result.output and "not a finite number" in result.output, result.output
    assert not out.exists()
