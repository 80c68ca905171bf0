"""GCP files: OpenDroneMap's gcp_list.txt (copr_kap's, against the survey's own GPS_average.txt),
the CSV format, check-point choice, and the checks of control against the block."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from pyproj import Geod
from shared_data import SHARED_DATA

from processing.gcp import GcpError, choose_check_points, read_csv_gcp, read_gcp, read_odm_gcp
from processing.handoff.block import read_block
from processing.handoff.control import validate_control
from processing.handoff.errors import HandoffInputError

COPR = SHARED_DATA / "copr_kap"
_GEOD = Geod(ellps="WGS84")


def _gps_average() -> dict[str, tuple[float, float]]:
    with (COPR / "GPS_average.txt").open() as handle:
        return {
            row["point name"]: (float(row["longitude"]), float(row["latitude"]))
            for row in csv.DictReader(handle)
        }


def test_copr_kap_gcp_list_reads_ten_points_and_27_observations() -> None:
    gcps = read_odm_gcp(COPR / "gcp_list.txt")
    assert len(gcps.points) == 10
    assert len(gcps.observations) == 27
    assert all(p.elevation_m == 0.0 for p in gcps.points)
    # Each point, converted from UTM 11N to WGS84, is a surveyed target position (to the 0.01 m the
    # UTM coordinates are written with).
    survey = _gps_average()
    for p in gcps.points:
        nearest = min(_GEOD.inv(p.lon_deg, p.lat_deg, lon, lat)[2] for lon, lat in survey.values())
        assert nearest < 0.01, p.name


def test_csv_in_lonlat_and_in_utm_read_the_same_points(tmp_path: Path) -> None:
    odm = read_odm_gcp(COPR / "gcp_list.txt")
    rows_ll = ["name,lon_deg,lat_deg,alt_m,image,x_px,y_px"]
    rows_en = ["name,easting_m,northing_m,alt_m,image,x_px,y_px"]
    for o in odm.observations:
        p = odm.point(o.point)
        rows_ll.append(
            f"{p.name},{p.lon_deg:.10f},{p.lat_deg:.10f},{p.elevation_m},{o.image},{o.x_px},{o.y_px}"
        )
        rows_en.append(
            f"{p.name},{p.source_xy[0]},{p.source_xy[1]},{p.elevation_m},{o.image},{o.x_px},{o.y_px}"
        )
    (tmp_path / "ll.csv").write_text("\n".join(rows_ll) + "\n")
    (tmp_path / "en.csv").write_text("\n".join(rows_en) + "\n")
    ll = read_gcp(tmp_path / "ll.csv")
    en = read_gcp(tmp_path / "en.csv", crs="EPSG:32611")
    for a in (ll, en):
        assert a.names == odm.names
        assert a.observations == odm.observations
        for p in a.points:
            q = odm.point(p.name)
            assert _GEOD.inv(p.lon_deg, p.lat_deg, q.lon_deg, q.lat_deg)[2] < 1e-3
    with pytest.raises(GcpError, match="--gcp-crs"):
        read_csv_gcp(tmp_path / "en.csv")


def test_an_unknown_crs_is_refused_with_the_fix(tmp_path: Path) -> None:
    text = (COPR / "gcp_list.txt").read_text().splitlines()
    (tmp_path / "gcp_list.txt").write_text("\n".join(["WGS84 UTM 99X", *text[1:]]) + "\n")
    with pytest.raises(GcpError, match="'WGS84 UTM 99X' is not a coordinate reference system"):
        read_gcp(tmp_path / "gcp_list.txt")


def test_a_point_with_two_positions_is_refused(tmp_path: Path) -> None:
    lines = (COPR / "gcp_list.txt").read_text().splitlines()
    first = lines[1].split("\t")
    first[0] = str(float(first[0]) + 5.0)
    (tmp_path / "gcp_list.txt").write_text("\n".join([lines[0], *lines[1:], "\t".join(first)]) + "\n")
    with pytest.raises(GcpError, match="one point, one position"):
        read_gcp(tmp_path / "gcp_list.txt")


def test_check_points_by_count_are_spread_over_the_block() -> None:
    names = [f"p{r}{c}" for r in range(3) for c in range(3)]
    xy = np.array([[c * 10.0, r * 10.0] for r in range(3) for c in range(3)])
    control, check = choose_check_points(names, xy, "1")
    assert check == ("p11",)  # the centre first
    control, check = choose_check_points(names, xy, "5")
    assert set(check) == {"p11", "p00", "p02", "p20", "p22"}
    assert set(control) == set(names) - set(check)
    control, check = choose_check_points(names, xy, "p00, p22")
    assert check == ("p00", "p22")
    with pytest.raises(GcpError, match="not a usable point"):
        choose_check_points(names, xy, "nope")
    with pytest.raises(GcpError, match="keep at least three"):
        choose_check_points(names, xy, "9")


@pytest.fixture(scope="module")
def copr_block():  # type: ignore[no-untyped-def]
    return read_block(COPR / "images")


def test_copr_kap_control_splits_and_notes_the_zero_elevations(copr_block) -> None:  # type: ignore[no-untyped-def]
    gcps = read_gcp(COPR / "gcp_list.txt")
    plan = validate_control(gcps, copr_block, "3")
    assert len(plan.check) == 3 and len(plan.control) >= 3
    assert any("0.0" in n for n in plan.notes)
    # The local ground frame keeps the surveyed distances (UTM grid distances differ by the
    # UTM scale factor, 0.9996 at the central meridian and larger 2.8 deg west of it).
    a, b = plan.control[0], plan.check[0]
    pa, pb = gcps.point(a), gcps.point(b)
    assert plan.surveyed_distance_m(a, b) == pytest.approx(
        _GEOD.inv(pa.lon_deg, pa.lat_deg, pb.lon_deg, pb.lat_deg)[2], abs=2e-3
    )


def _edited(tmp_path: Path, edit) -> Path:  # type: ignore[no-untyped-def]
    lines = (COPR / "gcp_list.txt").read_text().splitlines()
    out = tmp_path / "gcp_list.txt"
    out.write_text("\n".join([lines[0], *[edit(k, line) for k, line in enumerate(lines[1:])]]) + "\n")
    return out


def test_names_that_match_no_frame_are_refused(tmp_path: Path, copr_block) -> None:  # type: ignore[no-untyped-def]
    path = _edited(tmp_path, lambda k, line: line.replace("IMG_0037.jpg", "IMG_9999.jpg"))
    with pytest.raises(HandoffInputError, match=r"IMG_9999\.jpg"):
        validate_control(read_gcp(path), copr_block, None)


def test_pixels_outside_the_frame_are_refused(tmp_path: Path, copr_block) -> None:  # type: ignore[no-untyped-def]
    def edit(k: int, line: str) -> str:
        f = line.split("\t")
        if k == 0:
            f[3] = "3608.87"  # the original full-size x: the file was not scaled with the images
        return "\t".join(f)

    with pytest.raises(HandoffInputError, match=r"outside the image \(2136 x 1424 px\)"):
        validate_control(read_gcp(_edited(tmp_path, edit)), copr_block, None)


def test_fewer_than_three_usable_control_points_are_refused(tmp_path: Path, copr_block) -> None:  # type: ignore[no-untyped-def]
    gcps = read_gcp(COPR / "gcp_list.txt")
    seen = {p: len({o.image for o in gcps.observations_of(p)}) for p in gcps.names}
    usable = [p for p in gcps.names if seen[p] >= 2]
    with pytest.raises(HandoffInputError, match="usable control point"):
        validate_control(gcps, copr_block, str(len(usable) - 2))
