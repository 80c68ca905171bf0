"""The hand-off on a card as it comes: absolute altitudes and no ground elevation (pairs from the
camera positions, checked against nearest neighbours counted with pyproj's geodesic distances),
DJI relative altitudes and the card's own take-off frames (footprint pairs, checked against the
analytic overlap of nadir rectangles), and every engine's project without a ground."""

from __future__ import annotations

import contextlib
import json
import math
from pathlib import Path

import numpy as np
import pyexiv2
import pytest
from click.testing import CliRunner
from handoff_grid import FOOT_X_M, FOOT_Y_M, HEIGHT_M, grid, jpeg
from pyproj import Geod

from acquisition.exif import GeoTag, geotag_bytes
from processing.handoff.pairs import DEFAULT_LINE_NEIGHBOURS
from processing.handoff.prepare import prepare
from processing.handoff.takeoff import PAD_BAND_M, takeoff_ground
from sfap.cli import cli

_GEOD = Geod(ellps="WGS84")
LAT0, LON0 = 45.0, 7.0
DJI_NS = "http://www.dji.com/drone-dji/1.0/"


def _write(folder: Path, stations: list[tuple[float, float, float]], t0: float = 1.7e9) -> list[str]:
    """Frames at (east m, north m, altitude m AMSL) from (LON0, LAT0), 3 s apart, in this order."""
    folder.mkdir(parents=True, exist_ok=True)
    base = jpeg()
    names = []
    for k, (x, y, alt) in enumerate(stations):
        lon, lat, _ = _GEOD.fwd(LON0, LAT0, 90.0, x) if x else (LON0, LAT0, 0.0)
        lon, lat, _ = _GEOD.fwd(lon, lat, 0.0, y) if y else (lon, lat, 0.0)
        tag = GeoTag(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, time_utc_s=t0 + 3.0 * k, yaw_deg=0.0,
                     pitch_deg=0.0, roll_deg=0.0, xy_accuracy_m=1.5, z_accuracy_m=3.0)  # fmt: skip
        name = f"F{k:03d}.jpg"
        (folder / name).write_bytes(geotag_bytes(base, tag))
        names.append(name)
    return names


def _pairs(prepared, reason: str | None = None) -> set[frozenset[str]]:  # type: ignore[no-untyped-def]
    names = prepared.pairs.names(prepared.block)
    return {
        frozenset(p) for p, why in zip(names, prepared.pairs.reason, strict=True) if reason in (None, why)
    }


def _geodesic_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    def lonlat(p: tuple[float, float]) -> tuple[float, float]:
        lon, lat, _ = _GEOD.fwd(LON0, LAT0, 90.0, p[0]) if p[0] else (LON0, LAT0, 0.0)
        lon, lat, _ = _GEOD.fwd(lon, lat, 0.0, p[1]) if p[1] else (lon, lat, 0.0)
        return lon, lat

    (lon1, lat1), (lon2, lat2) = lonlat(a), lonlat(b)
    return float(_GEOD.inv(lon1, lat1, lon2, lat2)[2])


def test_absolute_altitudes_without_a_ground_pair_each_frame_with_its_nearest(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    xy = [(float(x), float(y)) for x, y in rng.uniform(0.0, 600.0, size=(30, 2))]
    names = _write(tmp_path / "img", [(x, y, 350.0) for x, y in xy])
    k = 5
    prepared = prepare(tmp_path / "img", position_neighbours=k, line_neighbours=0)
    assert prepared.ground is None and "pairs from the camera positions" in prepared.ground_description
    assert any("no ground elevation" in note for note in prepared.pairs.notes)
    assert set(prepared.pairs.reason) == {"position"}
    expected = set()
    for a in range(len(xy)):
        dist = sorted((_geodesic_m(xy[a], xy[b]), b) for b in range(len(xy)) if b != a)
        expected |= {frozenset((names[a], names[b])) for _, b in dist[:k]}
    assert _pairs(prepared) == expected


def test_line_neighbours_join_position_pairs_but_not_across_a_jump(tmp_path: Path) -> None:
    # One line of 6 frames 40 m apart, then a jump of 2 km to a second line of 6.
    stations = [(0.0, 40.0 * s, 350.0) for s in range(6)] + [(2000.0, 40.0 * s, 350.0) for s in range(6)]
    names = _write(tmp_path / "img", stations)
    prepared = prepare(tmp_path / "img", position_neighbours=1)
    # The nearest frame is the next along the line; with the line's next two, and nothing across
    # the jump (more than three median steps).
    want = {
        frozenset((names[first + i], names[first + i + step]))
        for first in (0, 6)
        for step in range(1, DEFAULT_LINE_NEIGHBOURS + 1)
        for i in range(6 - step)
    }
    assert _pairs(prepared) == want
    assert {"line", "position"} == set(prepared.pairs.reason)


def _nadir_grid_pairs(frames: list[tuple[str, float, float, int]]) -> set[frozenset[str]]:
    out = set()
    for i, a in enumerate(frames):
        for b in frames[i + 1 :]:
            ox = max(0.0, FOOT_X_M - abs(a[1] - b[1]))
            oy = max(0.0, FOOT_Y_M - abs(a[2] - b[2]))
            if 100.0 * ox * oy / (FOOT_X_M * FOOT_Y_M) >= 5.0:
                out.add(frozenset((a[0], b[0])))
    return out


def test_takeoff_frames_give_the_ground_and_the_footprint_pairs(tmp_path: Path) -> None:
    # Three frames on the pad at 250.2-251.0 m AMSL, then the grid flown 100 m above the pad's ground.
    ground = 250.0
    pad = [(-30.0, -30.0, ground + 0.4), (-30.5, -29.0, ground + 1.0), (-29.0, -30.2, ground + 0.2)]
    grid_stations = [(110.0 * line, 45.0 * s, ground + HEIGHT_M) for line in range(3) for s in range(5)]
    names = _write(tmp_path / "img", pad + grid_stations)
    prepared = prepare(tmp_path / "img")
    assert prepared.ground is not None
    desc = prepared.ground_description
    assert "take-off" in desc and "3 frame(s)" in desc and f"{ground + 0.4:.1f} m" in desc  # the median
    frames = [(names[3 + k], x, y, 0) for k, (x, y, _) in enumerate(grid_stations)]
    overlap = _pairs(prepared, "overlap")
    # The flat ground 0.4 m under the grid's own: the 100.4 m footprints only a fraction larger.
    assert overlap == _nadir_grid_pairs(frames)
    assert any("not survey frames" in n and names[0] in n for n in prepared.block.notes)


def test_takeoff_frames_are_only_the_first_ones_on_the_pad() -> None:
    names = [f"f{k}" for k in range(8)]
    xy = np.array([[0, 0], [1, 1], [60, 0], [120, 0], [180, 0], [240, 0], [300, 0], [360, 0]], float)
    alt = np.array([200.0, 200.0 + PAD_BAND_M / 2, 300, 300, 300, 300, 300, 300])
    found = takeoff_ground(names, xy, alt)
    assert (
        found is not None
        and found.names == ("f0", "f1")
        and found.elevation_m == pytest.approx(200.0 + PAD_BAND_M / 4)
    )
    # A block that starts in the air has no take-off frames; a low survey neither.
    assert takeoff_ground(names, xy, np.full(8, 300.0)) is None
    assert takeoff_ground(names, xy, np.where(alt > 250, 210.0, alt)) is None


def test_dji_relative_altitudes_give_the_ground_at_take_off(tmp_path: Path) -> None:
    frames = grid(tmp_path / "img", lines=3, per_line=5, dx_m=110.0, dy_m=45.0)
    with contextlib.suppress(RuntimeError, KeyError, ValueError):
        pyexiv2.registerNs(DJI_NS, "drone-dji")
    for name, *_ in frames:
        with pyexiv2.Image(str(tmp_path / "img" / name)) as image:
            image.modify_exif({"Exif.GPSInfo.GPSAltitude": "35000/100"})  # 350 m AMSL: the GPS says
            image.modify_xmp({"Xmp.drone-dji.RelativeAltitude": f"+{HEIGHT_M:.2f}"})
    prepared = prepare(tmp_path / "img")
    assert prepared.ground is not None and "take-off point" in prepared.ground_description
    assert any("RelativeAltitude" in n for n in prepared.block.notes)
    overlap = _pairs(prepared, "overlap")
    assert overlap == _nadir_grid_pairs(frames)


@pytest.mark.parametrize("engine", ["colmap", "odm", "metashape", "pix4d"])
def test_every_engine_gets_its_project_without_a_ground(tmp_path: Path, engine: str) -> None:
    grid(tmp_path / "img", lines=3, per_line=5, dx_m=110.0, dy_m=45.0)
    result = CliRunner().invoke(
        cli, ["handoff", str(tmp_path / "img"), "--to", engine, "-o", str(tmp_path / "w"), "--json"]
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert "pairs from the camera positions" in report["project"]["ground"]
    assert any("no ground elevation" in n for n in report["project"]["notes"])
    if engine == "odm":
        geo = (tmp_path / "w" / "geo.txt").read_text().splitlines()
        assert len(geo) == 1 + 15 and all(math.isfinite(float(v)) for v in geo[1].split()[1:])
    if engine == "colmap":
        assert (tmp_path / "w" / "pairs.txt").read_text().count("\n") == report["project"]["pairs"]["count"]
