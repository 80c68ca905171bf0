"""The plan folder (``sfap plan -o DIR``): its one writer and its one reader.

Writing (:func:`write_outputs`): every output of a plan into one folder, all or nothing. The
files (what a field team opens them with):

- mission.plan: QGroundControl; mission.waypoints: Mission Planner, MAVProxy, QGC (WPL 110)
- flight_lines.geojson, stations.geojson, footprints.geojson, area.geojson: any GIS
- mission.kml: Google Earth
- map.png: a person, at a glance
- summary.json: the numbers that justify the plan (:func:`summary_json`)
- a terrain plan's DEM, under its own name, clipped to the area and home with a margin (what
  the plan was made on; :attr:`PlanFolder.dem_path` finds it), so the folder is self-contained

Reading (:func:`read_plan_folder`): what the rest of sfap (the monitor, the check, the re-fly)
needs from a plan folder, typed: the :class:`~planner.plan.Summary`, home, one
:class:`PassSummary` per pass (its trigger distance among them), the terrain as a
:class:`~planner.terrain_follow.TerrainSummary`, the stations (:class:`PlannedStations`) and the
area. The same types are what :func:`summary_json` writes from, so the two sides cannot drift.
"""

from __future__ import annotations

import json
import logging
import os
import typing
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon, shape

from .aside import Aside, Helper, start_aside
from .camera import Orientation
from .errors import PlanFolderError
from .kinds import PassKind
from .mission import HomePosition
from .outputs import atomic_write_text, staged_output_dir
from .plan import FlightPass, Summary, SurveyPlan
from .terrain_follow import TerrainSummary

log = logging.getLogger(__name__)

SUMMARY_FILE = "summary.json"
STATIONS_FILE = "stations.geojson"
AREA_FILE = "area.geojson"

#: Files that make a folder a plan folder.
PLAN_FILES = (SUMMARY_FILE, STATIONS_FILE)

#: Every file :func:`write_outputs` writes, in the order it writes them.
OUTPUT_FILES = (
    "mission.plan",
    "mission.waypoints",
    "flight_lines.geojson",
    STATIONS_FILE,
    "footprints.geojson",
    AREA_FILE,
    "mission.kml",
    "map.png",
    SUMMARY_FILE,
)


@dataclass(frozen=True, kw_only=True)
class PassSummary:
    """One pass as summary.json's ``passes`` lists it.

    ``direction_deg``: true bearing of the lines (0-180); ``tilt_deg``: camera off nadir;
    ``look_heading_deg``: true bearing the camera looks toward (obliques), else None;
    ``alt_agl_m``: planned height above ground; ``trigger_distance_m``: the distance between
    exposures along the lines; ``segment_count``: camera-on segments; ``near_gsd_cm`` /
    ``far_gsd_cm``: finest and coarsest GSD in a frame.
    """

    index: int
    kind: PassKind
    name: str
    direction_deg: float
    tilt_deg: float
    look_heading_deg: float | None
    alt_agl_m: float
    line_spacing_m: float
    trigger_distance_m: float
    segment_count: int
    photo_count: int
    near_gsd_cm: float
    far_gsd_cm: float

    @classmethod
    def of_pass(cls, flight_pass: FlightPass, photo_count: int) -> PassSummary:
        p = flight_pass
        return cls(
            index=p.index,
            kind=p.kind,
            name=p.name,
            direction_deg=p.direction_deg,
            tilt_deg=p.tilt_deg,
            look_heading_deg=p.look_heading_deg,
            alt_agl_m=p.alt_agl_m,
            line_spacing_m=p.line_spacing_m,
            trigger_distance_m=p.trigger_distance_m,
            segment_count=len(p.lines),
            photo_count=photo_count,
            near_gsd_cm=p.near_gsd_cm,
            far_gsd_cm=p.far_gsd_cm,
        )

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["kind"] = self.kind.value
        return out


@dataclass(frozen=True, kw_only=True)
class PlannedStations:
    """stations.geojson as columns, one row per planned exposure in flight order.

    - ``station``: the 0-based index in flight order (the ``station`` property);
      ``pass_index``, ``line_index``: the pass and the line within it.
    - ``lon_deg``, ``lat_deg``: WGS84; ``alt_rel_home_m``: commanded altitude above home;
      ``alt_agl_m``: above the ground below, None when the file does not give it for every station.
    - ``heading_deg``: true bearing of flight; ``look_heading_deg``: true bearing the optical axis
      points toward; ``tilt_deg``: off nadir; ``gsd_cm``: where the optical axis meets the ground.
    """

    station: NDArray[np.int64]
    pass_index: NDArray[np.int64]
    line_index: NDArray[np.int64]
    lon_deg: NDArray[np.float64]
    lat_deg: NDArray[np.float64]
    alt_rel_home_m: NDArray[np.float64]
    alt_agl_m: NDArray[np.float64] | None
    heading_deg: NDArray[np.float64]
    look_heading_deg: NDArray[np.float64]
    tilt_deg: NDArray[np.float64]
    gsd_cm: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.lon_deg.shape[0])


@dataclass(frozen=True, kw_only=True)
class PlanFolder:
    """A plan folder as read (:func:`read_plan_folder`).

    ``summary``: summary.json's figures; ``home``: the take-off position (None when the summary
    records none); ``passes``: per pass, in the summary's order; ``terrain``: how the terrain
    shaped the plan, None for a plan over flat ground; ``area_lonlat`` / ``exclusions_lonlat``:
    area.geojson (None / empty when the folder has no area file); ``extra``: the other sections
    of summary.json (``sorties``, ``scales``...) as read.
    """

    folder: Path
    summary: Summary
    home: HomePosition | None
    passes: tuple[PassSummary, ...]
    terrain: TerrainSummary | None
    stations: PlannedStations
    area_lonlat: Polygon | MultiPolygon | None
    exclusions_lonlat: tuple[Polygon, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def name(self) -> str:
        return self.summary.name

    @property
    def dem_path(self) -> Path | None:
        """A terrain plan's DEM in its folder (clipped to the area and home with a margin: what
        the plan was made on), None for a plan over flat ground or an older folder without it."""
        if self.terrain is None or not self.terrain.dem:
            return None
        for name in (Path(self.terrain.dem).name, f"dem-{Path(self.terrain.dem).name}"):
            if (self.folder / name).is_file():
                return self.folder / name
        return None

    @property
    def orientation(self) -> Orientation:
        return Orientation(self.summary.orientation)

    def trigger_distance_m(self, pass_index: int) -> float:
        """The trigger distance of pass ``pass_index``; the plan's (the nadir pass's) when the
        summary lists no such pass."""
        for p in self.passes:
            if p.index == pass_index:
                return p.trigger_distance_m
        return self.summary.trigger_distance_m


# --- writing ------------------------------------------------------------------------------------


def pass_summaries(plan: SurveyPlan) -> tuple[PassSummary, ...]:
    return tuple(
        PassSummary.of_pass(p, int((plan.stations.pass_index == p.index).sum())) for p in plan.passes
    )


def summary_json(plan: SurveyPlan) -> str:
    """summary.json: :class:`~planner.plan.Summary`, the home position and the passes."""
    data = plan.summary.as_dict()
    data["home"] = {
        "lat_deg": plan.home.lat_deg,
        "lon_deg": plan.home.lon_deg,
        "alt_amsl_m": plan.home.alt_amsl_m,
    }
    data["passes"] = [p.as_dict() for p in pass_summaries(plan)]
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def dem_file_name(plan: SurveyPlan) -> str | None:
    """The name of the DEM a terrain plan carries in its folder (the name its summary records,
    the DEM's own), None for a plan over flat ground."""
    terrain = plan.summary.terrain
    if terrain is None or plan.layout is None or plan.layout.dem is None:
        return None
    name = str(terrain["dem"])
    return name if name not in OUTPUT_FILES else f"dem-{name}"


#: Above this many photos the footprints are written as a GeoPackage (GPKG_FILE, layer
#: footprints) instead of footprints.geojson: a GIS opens it through its spatial index instead
#: of parsing every polygon. stations.geojson stays (the reader's file).
GPKG_ABOVE_PHOTOS = 100_000
GPKG_FILE = "footprints.gpkg"


def output_files(plan: SurveyPlan) -> tuple[str, ...]:
    """Every file :func:`write_outputs` writes for ``plan``, in order: OUTPUT_FILES (a large
    plan's footprints as GPKG_FILE instead), then a terrain plan's DEM."""
    names: tuple[str, ...] = OUTPUT_FILES
    if len(plan.stations) > GPKG_ABOVE_PHOTOS:
        names = tuple(GPKG_FILE if n == "footprints.geojson" else n for n in names)
    dem = dem_file_name(plan)
    return names if dem is None else (*names, dem)


def _writers(plan: SurveyPlan) -> dict[str, Callable[[Path], object]]:
    """The writer of each file of :func:`output_files` but map.png, by name."""
    from .formats.geojson import (
        write_area_geojson,
        write_flight_lines_geojson,
        write_footprints_geojson,
        write_stations_geojson,
    )
    from .formats.kml import write_kml
    from .formats.qgc_plan import write_plan
    from .formats.waypoints import write_waypoints

    writers: dict[str, Callable[[Path], object]] = {
        "mission.plan": lambda p: write_plan(plan.mission, p),
        "mission.waypoints": lambda p: write_waypoints(plan.mission, p),
        "flight_lines.geojson": lambda p: write_flight_lines_geojson(plan, p),
        STATIONS_FILE: lambda p: write_stations_geojson(plan, p),
        "footprints.geojson": lambda p: write_footprints_geojson(plan, p),
        AREA_FILE: lambda p: write_area_geojson(plan, p),
        "mission.kml": lambda p: write_kml(plan, p),
        SUMMARY_FILE: lambda p: atomic_write_text(p, summary_json(plan)),
    }
    if len(plan.stations) > GPKG_ABOVE_PHOTOS:
        from .formats.geopackage import write_footprints_gpkg

        writers[GPKG_FILE] = lambda p: write_footprints_gpkg(plan, p)
    dem_name = dem_file_name(plan)
    if dem_name is not None:
        assert plan.layout is not None and plan.layout.dem is not None
        dem = plan.layout.dem
        writers[dem_name] = lambda p: dem.write_geotiff(p)
    return writers


def write_outputs(
    plan: SurveyPlan,
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
    helper: Helper | None = None,
    map_begun: Aside | None = None,
) -> list[Path]:
    """Write every output file; on any failure nothing is left behind and ``out_dir`` is
    unchanged. ``progress(1)`` is called after each file.

    map.png, a third of a small plan's time, is drawn aside (planner.aside: in a child process
    on the other core, where that is safe) from the moment the staging folder exists, while the
    other files are written here; it is waited for before the folder is moved into place. A
    ``helper`` (started with planner.maprender.prepare before the plan was made) draws it
    instead, with Pillow and the fonts already loaded: it is sent the map's view of the plan
    (planner.mapview), which it reads without importing the planner. ``map_begun``: the map
    begun by such a helper during the planning (planner.plan_run.plan_spec), sent here its
    header, caption and path in the staging folder."""
    from .mapview import map_texts, map_view, write_map_png

    names = output_files(plan)
    final = Path(out_dir)
    with staged_output_dir(final, overwrite=overwrite) as staging:
        map_path, what = staging / "map.png", str(final / "map.png")
        if map_begun is not None:
            map_png, map_png.what = map_begun, what
            map_png.send((*map_texts(plan), map_path))
        elif helper is not None:
            map_png = helper.submit(write_map_png, map_view(plan), map_path, what=what)
        else:
            view = map_view(plan)
            map_png = start_aside(lambda: write_map_png(view, map_path), what)
        try:
            writers = _writers(plan)
            for name in names:
                if name == "map.png":
                    continue
                log.debug("writing %s", name)
                writers[name](staging / name)
                if progress is not None:
                    progress(1)
            map_png.wait()
        except BaseException:
            map_png.cancel()
            raise
        if progress is not None:
            progress(1)
    return [final / name for name in names]


# --- reading ------------------------------------------------------------------------------------


def is_plan_folder(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a folder written by ``sfap plan`` (it holds summary.json and
    stations.geojson)."""
    folder = Path(path)
    return folder.is_dir() and all((folder / name).is_file() for name in PLAN_FILES)


def read_plan_folder(plan_dir: str | os.PathLike[str]) -> PlanFolder:
    """Read a folder written by ``sfap plan -o DIR``.

    Raises :class:`~planner.errors.PlanFolderError` (exit code 2) naming the folder or the file
    and the value when the folder is not a plan folder, or a file cannot be read or lacks a value.
    """
    folder = Path(plan_dir)
    if not is_plan_folder(folder):
        raise PlanFolderError(
            f"{folder} is not a plan folder (it needs {' and '.join(PLAN_FILES)}); give the folder "
            "`sfap plan ... -o FOLDER` wrote"
        )
    summary_path = folder / SUMMARY_FILE
    data = _read_json(summary_path)
    if not isinstance(data, dict):
        raise PlanFolderError(f"{summary_path} is not a JSON object; re-run `sfap plan`")
    try:
        summary = _summary_from_dict(data, folder.name)
        home_data = data.get("home")
        home = None if not home_data else HomePosition(**{k: float(v) for k, v in home_data.items()})
        passes = tuple(_pass_from_dict(p) for p in data.get("passes", []))
        terrain = None if not data.get("terrain") else _terrain_from_dict(data["terrain"])
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise PlanFolderError(f"{summary_path}: missing or bad value {error}; re-run `sfap plan`") from None
    known = {f.name for f in fields(Summary)} | {"home", "passes"}
    area, exclusions = _read_area(folder / AREA_FILE)
    return PlanFolder(
        folder=folder,
        summary=summary,
        home=home,
        passes=passes,
        terrain=terrain,
        stations=_read_stations(folder / STATIONS_FILE),
        area_lonlat=area,
        exclusions_lonlat=exclusions,
        extra={k: v for k, v in data.items() if k not in known},
    )


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise PlanFolderError(f"{path} cannot be read as JSON ({error}); re-run `sfap plan`") from None


def _typed(value: Any, hint: Any) -> Any:
    """``value`` as read from JSON, made the type ``hint`` of a dataclass field says."""
    options = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, type(int | str)) else ()
    if options and type(None) in options:
        if value is None:
            return None
        (hint,) = [o for o in options if o is not type(None)]
    origin = typing.get_origin(hint)
    if hint is float:
        return float(value)
    if hint is int:
        if isinstance(value, float) and not value.is_integer():
            raise ValueError(f"{value!r} is not a whole number")
        return int(value)
    if hint is str:
        if not isinstance(value, str):
            raise TypeError(f"{value!r} is not a string")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise TypeError(f"{value!r} is not true or false")
        return value
    if origin is tuple:
        (item,) = typing.get_args(hint)[:1]
        return tuple(_typed(v, item) for v in value)
    if origin is dict:
        if not isinstance(value, dict):
            raise TypeError(f"{value!r} is not a JSON object")
        return value
    if isinstance(hint, type) and issubclass(hint, PassKind):
        return PassKind(value)
    raise TypeError(f"no reader for {hint!r}")  # a field type this module does not know yet


def _from_dict(cls: type, data: dict[str, Any], **given: Any) -> Any:
    hints = typing.get_type_hints(cls)
    values = dict(given)
    for f in fields(cls):
        if f.name in values:
            continue
        if f.name not in data:
            if f.default is not MISSING or f.default_factory is not MISSING:  # may be absent (older plans)
                continue
            raise KeyError(f.name)
        try:
            values[f.name] = _typed(data[f.name], hints[f.name])
        except (TypeError, ValueError) as error:
            raise ValueError(f"{f.name!r} ({error})") from None
    return cls(**values)


def _summary_from_dict(data: dict[str, Any], folder_name: str) -> Summary:
    name = data.get("name", folder_name)
    return typing.cast(Summary, _from_dict(Summary, data, name=str(name)))


def _pass_from_dict(data: dict[str, Any]) -> PassSummary:
    return typing.cast(PassSummary, _from_dict(PassSummary, data))


def _terrain_from_dict(data: dict[str, Any]) -> TerrainSummary:
    return typing.cast(TerrainSummary, _from_dict(TerrainSummary, data))


def _read_stations(path: Path) -> PlannedStations:
    data = _read_json(path)
    features = data.get("features") if isinstance(data, dict) else None
    if not isinstance(features, list):
        raise PlanFolderError(f"{path} is not a GeoJSON FeatureCollection; re-run `sfap plan`")
    try:
        props = [f["properties"] for f in features]

        def column(key: str) -> NDArray[np.float64]:
            return np.array([p[key] for p in props], dtype=np.float64).reshape(len(props))

        def whole(key: str) -> NDArray[np.int64]:
            return np.array([int(p[key]) for p in props], dtype=np.int64).reshape(len(props))

        agl_values = [p.get("alt_agl_m") for p in props]
        stations = PlannedStations(
            station=np.array([int(p.get("station", k)) for k, p in enumerate(props)], dtype=np.int64),
            pass_index=whole("pass"),
            line_index=whole("line"),
            lon_deg=column("lon_deg"),
            lat_deg=column("lat_deg"),
            alt_rel_home_m=column("alt_rel_home_m"),
            alt_agl_m=(
                np.array(agl_values, dtype=np.float64) if agl_values and None not in agl_values else None
            ),
            heading_deg=column("heading_deg"),
            look_heading_deg=column("look_heading_deg"),
            tilt_deg=column("tilt_deg"),
            gsd_cm=column("gsd_cm"),
        )
    except (KeyError, TypeError, ValueError) as error:
        raise PlanFolderError(f"{path}: a station lacks {error}; re-run `sfap plan`") from None
    return stations


def _read_area(path: Path) -> tuple[Polygon | MultiPolygon | None, tuple[Polygon, ...]]:
    if not path.is_file():
        return None, ()
    data = _read_json(path)
    areas: list[Polygon | MultiPolygon] = []
    exclusions: list[Polygon] = []
    try:
        for feature in data.get("features", []):
            geom = shape(feature["geometry"])
            kind = feature.get("properties", {}).get("kind")
            if kind == "exclusion" and isinstance(geom, Polygon):
                exclusions.append(geom)
            elif kind == "area" and isinstance(geom, Polygon | MultiPolygon):
                areas.append(geom)
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise PlanFolderError(f"{path}: a feature lacks {error}; re-run `sfap plan`") from None
    if not areas:
        return None, tuple(exclusions)
    if len(areas) == 1:
        return areas[0], tuple(exclusions)
    return MultiPolygon([p for a in areas for p in getattr(a, "geoms", [a])]), tuple(exclusions)
