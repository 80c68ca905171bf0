"""The plan folder's reader against its writer's own objects: every plan written by
write_outputs reads back as the SurveyPlan it came from (the summary exactly, JSON floats being
round-trip exact; stations within the files' rounding), on the plans that exercise each part
(several passes, terrain, sorties); and each kind of damage to a folder is a PlanFolderError
that names the file and the value."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import shapely
from survey_oracles import MISSIONS, make_spec
from test_survey import to_lonlat_polygon

from planner.errors import InputError, PlanFolderError
from planner.formats.geojson import COORD_DECIMALS
from planner.kinds import PassKind
from planner.plan import SurveyPlan
from planner.plan_folder import (
    OUTPUT_FILES,
    PLAN_FILES,
    PlanFolder,
    is_plan_folder,
    read_plan_folder,
    write_outputs,
)
from planner.spec import load_spec
from planner.survey import plan_polygons, plan_survey

Written = tuple[SurveyPlan, Path]


def _oblique_block() -> SurveyPlan:
    """A small block with a crosshatch and two oblique passes (their own look headings)."""
    spec = make_spec(
        {"crosshatch": True, "oblique": [{"tilt_deg": 30.0, "headings_deg": [0, 90]}]},
    )
    square = [(0, 0), (160, 0), (160, 120), (0, 120)]
    return plan_polygons(spec, [to_lonlat_polygon(square)], [])


@pytest.fixture(scope="module", params=["oblique-block", "field-multiscale", "bardenas-gully-terrain"])
def written(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Written:
    """Obliques and a crosshatch; two scales with their own trigger distances; terrain."""
    if request.param == "oblique-block":
        plan = _oblique_block()
    else:
        plan = plan_survey(load_spec(MISSIONS / f"{request.param}.toml"))
    folder = tmp_path_factory.mktemp("plans") / request.param
    dem = ["bardenas-gully-dem.tif"] if request.param == "bardenas-gully-terrain" else []
    assert [p.name for p in write_outputs(plan, folder)] == [*OUTPUT_FILES, *dem]
    return plan, folder


def test_the_summary_reads_back_as_written(written: Written) -> None:
    plan, folder = written
    read = read_plan_folder(folder)
    assert isinstance(read, PlanFolder) and is_plan_folder(folder)
    assert read.summary == plan.summary
    assert read.name == plan.name and read.orientation is plan.orientation
    assert read.home == plan.home


def test_the_passes_carry_each_pass_and_its_trigger_distance(written: Written) -> None:
    plan, folder = written
    read = read_plan_folder(folder)
    assert len(read.passes) == len(plan.passes) >= 1
    for got, flown in zip(read.passes, plan.passes, strict=True):
        assert got.index == flown.index and got.kind is flown.kind and isinstance(got.kind, PassKind)
        assert got.trigger_distance_m == flown.trigger_distance_m
        assert read.trigger_distance_m(flown.index) == flown.trigger_distance_m
        assert got.line_spacing_m == flown.line_spacing_m and got.look_heading_deg == flown.look_heading_deg
        assert got.segment_count == len(flown.lines)
        assert got.photo_count == int(np.count_nonzero(plan.stations.pass_index == flown.index))
    assert sum(p.photo_count for p in read.passes) == len(plan.stations)
    # a pass the summary does not list falls back on the plan's trigger distance
    assert read.trigger_distance_m(max(p.index for p in plan.passes) + 1) == plan.summary.trigger_distance_m


def test_the_terrain_is_a_typed_summary(written: Written) -> None:
    plan, folder = written
    read = read_plan_folder(folder)
    if plan.summary.terrain is None:
        assert read.terrain is None
    else:
        assert read.terrain is not None
        assert dataclasses.asdict(read.terrain) == plan.summary.terrain
        assert isinstance(read.terrain.follow, bool) and isinstance(read.terrain.waypoints_added, int)


def test_the_stations_and_the_area_read_back_within_the_files_rounding(
    written: tuple[SurveyPlan, Path],
) -> None:
    plan, folder = written
    st, planned = read_plan_folder(folder).stations, plan.stations
    assert len(st) == len(planned)
    np.testing.assert_array_equal(st.station, np.arange(len(planned)))
    np.testing.assert_array_equal(st.pass_index, planned.pass_index)
    np.testing.assert_array_equal(st.line_index, planned.line_index)
    np.testing.assert_allclose(st.lon_deg, planned.lon_deg, atol=1e-8)
    np.testing.assert_allclose(st.lat_deg, planned.lat_deg, atol=1e-8)
    for name in ("alt_rel_home_m", "heading_deg", "look_heading_deg", "tilt_deg"):
        np.testing.assert_allclose(getattr(st, name), getattr(planned, name), atol=0.005 + 1e-9)
    assert st.alt_agl_m is not None
    np.testing.assert_allclose(st.alt_agl_m, planned.alt_agl_m, atol=0.005 + 1e-9)
    np.testing.assert_allclose(st.gsd_cm, planned.gsd_cm, atol=0.0005 + 1e-9)
    read = read_plan_folder(folder)
    assert read.area_lonlat is not None
    # the vertices are rounded to COORD_DECIMALS: the outline moves by at most half a step
    moved = plan.area_lonlat.length * 0.5 * 10.0**-COORD_DECIMALS * 2**0.5
    assert read.area_lonlat.symmetric_difference(plan.area_lonlat).area <= moved
    assert len(read.exclusions_lonlat) == len(plan.exclusions_lonlat)


def test_a_sortie_plan_keeps_its_sorties_section(quarry_sorties_cli: tuple[Path, int, str, str]) -> None:
    from planner.sorties import split_sorties

    # The folder `sfap plan` wrote for this spec (write_with_sorties, shared with the CLI's tests),
    # read back against the plan and sorties planned here.
    folder, exit_code, _, output = quarry_sorties_cli
    assert exit_code == 0, output
    plan = plan_survey(load_spec(MISSIONS / "quarry-block-sorties.toml"))
    sorties = split_sorties(plan)
    read = read_plan_folder(folder)
    assert read.summary == plan.summary
    assert read.extra["sorties"]["count"] == len(sorties) > 1
    first = read_plan_folder(next(p for p in sorted(folder.iterdir()) if p.is_dir()))
    assert first.summary == sorties[0].plan.summary


def _copy(folder: Path, tmp_path: Path) -> Path:
    target = tmp_path / "copy"
    shutil.copytree(folder, target)
    return target


def test_damaged_folders_are_named_errors(written: Written, tmp_path: Path) -> None:
    _, folder = written
    with pytest.raises(
        PlanFolderError, match=r"not a plan folder.*summary.json and stations.geojson.*sfap plan"
    ):
        read_plan_folder(tmp_path)
    assert issubclass(PlanFolderError, InputError) and PlanFolderError.exit_code == 2

    copy = _copy(folder, tmp_path)
    for name in PLAN_FILES:
        moved = copy / name
        moved.rename(copy / "aside")
        assert not is_plan_folder(copy)
        with pytest.raises(PlanFolderError, match="not a plan folder"):
            read_plan_folder(copy)
        (copy / "aside").rename(moved)

    (copy / "summary.json").write_text("{not json")
    with pytest.raises(PlanFolderError, match=r"summary.json cannot be read as JSON"):
        read_plan_folder(copy)

    summary = json.loads((folder / "summary.json").read_text())
    summary["gsd_cm"] = "fine"
    (copy / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(PlanFolderError, match=r"summary.json: missing or bad value.*'gsd_cm'"):
        read_plan_folder(copy)

    summary = json.loads((folder / "summary.json").read_text())
    del summary["passes"][0]["trigger_distance_m"]
    (copy / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(PlanFolderError, match="trigger_distance_m"):
        read_plan_folder(copy)

    shutil.copy(folder / "summary.json", copy / "summary.json")
    stations = json.loads((folder / "stations.geojson").read_text())
    del stations["features"][3]["properties"]["lat_deg"]
    (copy / "stations.geojson").write_text(json.dumps(stations))
    with pytest.raises(PlanFolderError, match=r"stations.geojson: a station lacks 'lat_deg'"):
        read_plan_folder(copy)


def test_a_terrain_plan_carries_its_dem_clipped_and_reads_it_back(tmp_path: Path) -> None:
    """The folder is self-contained: the DEM the plan was made on, clipped to the area with a
    margin, is in it (the check, the monitor and the re-fly find it there), its elevations the
    original's; sorties carry it too; a flat plan carries none."""
    import rasterio

    from planner.plan_run import plan_spec
    from planner.terrain import Dem

    source = (
        (MISSIONS / "bardenas-gully-terrain.toml")
        .read_text()
        .replace('"bardenas-gully', f'"{MISSIONS}/bardenas-gully')
    )
    spec_file = tmp_path / "gully.toml"
    spec_file.write_text(source.replace("[vehicle]\n", "[vehicle]\nendurance_s = 1500\n"))
    run = plan_spec(spec_file)
    assert run.sorties
    written = run.write(tmp_path / "out")
    assert len(written) == run.file_count  # the progress bar's count
    folder = read_plan_folder(tmp_path / "out")
    assert folder.dem_path == tmp_path / "out" / "bardenas-gully-dem.tif"
    original = Dem.from_geotiff(MISSIONS / "bardenas-gully-dem.tif")
    with rasterio.open(MISSIONS / "bardenas-gully-dem.tif") as a, rasterio.open(folder.dem_path) as b:
        assert b.crs == a.crs and b.res == a.res
        # clipped: no larger than the original, and it holds every station with its footprint
        assert b.width * b.height <= a.width * a.height
    st = folder.stations
    x, y = np.asarray(st.lon_deg), np.asarray(st.lat_deg)
    from pyproj import Transformer

    e, n = Transformer.from_crs("EPSG:4326", original.crs, always_xy=True).transform(x, y)
    with rasterio.open(MISSIONS / "bardenas-gully-dem.tif") as a, rasterio.open(folder.dem_path) as b:
        za = np.array([v[0] for v in a.sample(zip(e, n, strict=True))])
        zb = np.array([v[0] for v in b.sample(zip(e, n, strict=True))])
    np.testing.assert_allclose(zb, za, atol=1e-3)
    for k in range(1, len(run.sorties) + 1):
        sortie = read_plan_folder(tmp_path / "out" / f"sortie-{k:02d}")
        assert sortie.dem_path is not None and sortie.dem_path.parent == sortie.folder
    flat = plan_survey(load_spec(MISSIONS / "bardenas-gully.toml"))
    write_outputs(flat, tmp_path / "flat")
    assert read_plan_folder(tmp_path / "flat").dem_path is None
    assert not list((tmp_path / "flat").glob("*.tif"))


def test_a_large_plan_writes_its_footprints_as_a_geopackage(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Above the stated size the footprints go to a GeoPackage instead of footprints.geojson;
    read back by GDAL through pyogrio, feature for feature."""
    from pyogrio import list_layers
    from pyogrio.raw import read

    import planner.plan_folder as pf

    plan = plan_survey(load_spec(MISSIONS / "field-concave.toml"))
    monkeypatch.setattr(pf, "GPKG_ABOVE_PHOTOS", len(plan.stations) - 1)
    names = [p.name for p in write_outputs(plan, tmp_path / "out")]
    assert "footprints.gpkg" in names and "footprints.geojson" not in names and "stations.geojson" in names
    gpkg = tmp_path / "out" / "footprints.gpkg"
    assert [str(n) for n, _ in list_layers(gpkg)] == ["footprints"]
    st = plan.stations
    meta, _, polygons, fields = read(gpkg, layer="footprints")
    assert meta["crs"] == "EPSG:4326"
    column = dict(zip(meta["fields"], fields, strict=True))
    np.testing.assert_array_equal(column["station"], np.arange(len(st)))
    np.testing.assert_array_equal(column["line"], st.line_index)
    np.testing.assert_allclose(column["gsd_cm"], st.gsd_cm)
    shapes = shapely.from_wkb(polygons)
    assert len(shapes) == len(st) and all(shapely.is_ccw(s.exterior) for s in shapes)
    expected = shapely.polygons(st.footprint_lonlat_deg)
    assert np.all(shapely.equals_exact(shapely.normalize(shapes), shapely.normalize(expected), 1e-12))
    assert read_plan_folder(tmp_path / "out").stations.lon_deg.shape == (len(st),)  # the reader's file stays
