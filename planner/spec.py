"""The mission spec: a TOML file that describes one survey (stdlib tomllib).

Paths in the file are relative to the file. Unknown keys are errors that list the valid keys;
every value is checked against its range with a message that names the key and the fix.
See missions/*.toml for examples and README.md for every key.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

from .camera import Camera, Orientation
from .errors import SpecError
from .mission import Autopilot, VehicleType


class TriggerMode(StrEnum):
    DISTANCE = "distance"  # DO_SET_CAM_TRIGG_DIST along each line
    HOVER = "hover"  # stop and shoot at every station


@dataclass(frozen=True, kw_only=True)
class ObliqueSpec:
    """Convergent oblique passes: the camera tilted ``tilt_deg`` off nadir toward each heading."""

    tilt_deg: float
    headings_deg: tuple[float, ...]


@dataclass(frozen=True, kw_only=True)
class ScaleSpec:
    """A further nadir pass over the same area at another height (multi-scale blocks, against
    the doming effect: James and Robson 2014); ``None`` overlaps take the survey's."""

    gsd_cm: float | None
    altitude_agl_m: float | None
    front_overlap_pct: float | None
    side_overlap_pct: float | None


@dataclass(frozen=True, kw_only=True)
class SurveySpec:
    gsd_cm: float | None
    altitude_agl_m: float | None
    front_overlap_pct: float
    side_overlap_pct: float
    speed_m_s: float
    direction_deg: float | None  # None: "auto"
    crosshatch: bool
    turnaround_m: float
    trigger: TriggerMode
    oblique: tuple[ObliqueSpec, ...]
    adjust_speed: bool  # lower the speed to the highest safe one instead of refusing
    max_blur_px: float
    transit_speed_m_s: float | None
    hover_hold_s: float
    exclusion_clearance_m: float
    oblique_front_overlap_pct: float | None
    oblique_side_overlap_pct: float | None
    #: Further passes at other heights ([[survey.scale]]), flown after the main passes.
    scales: tuple[ScaleSpec, ...] = ()
    #: "one_mission": the scales follow in the same mission; "sorties": each pass height is
    #: flown (and split by endurance) as its own set of sorties.
    scale_flight: str = "one_mission"


@dataclass(frozen=True, kw_only=True)
class VehicleSpec:
    type: VehicleType
    home_lat_deg: float | None
    home_lon_deg: float | None
    home_alt_amsl_m: float
    takeoff_alt_m: float
    max_alt_agl_m: float
    autopilot: Autopilot
    climb_rate_m_s: float
    #: The longest flight one battery allows (a longer plan is flagged), minutes.
    max_flight_time_min: float = 30.0
    #: Endurance of one battery, seconds (given, or battery_capacity_mah / consumption_ma);
    #: None: the plan is not split into sorties (planner.sorties).
    endurance_s: float | None = None
    #: Reserve kept in the battery at landing: the larger of the share and the seconds.
    reserve_pct: float = 20.0
    reserve_s: float = 0.0

    # Fixed wing (planner.fixed_wing): the turn radius follows from the speed and the bank limit.
    bank_limit_deg: float = 30.0
    airspeed_min_m_s: float = 9.0  # ArduPlane AIRSPEED_MIN default
    airspeed_max_m_s: float = 22.0  # ArduPlane AIRSPEED_MAX default
    takeoff_pitch_deg: float = 15.0  # NAV_TAKEOFF param1
    landing_glide_slope_deg: float = 6.0
    landing_heading_deg: float | None = None  # true bearing flown on the final approach; None: auto

    @property
    def usable_flight_s(self) -> float | None:
        """The longest sortie allowed: endurance less the reserve (None without endurance)."""
        if self.endurance_s is None:
            return None
        return self.endurance_s - max(self.endurance_s * self.reserve_pct / 100.0, self.reserve_s)


@dataclass(frozen=True, kw_only=True)
class TerrainSpec:
    """A DEM and how to fly over it (planner.terrain_follow)."""

    dem_path: Path
    follow: bool = True  # altitudes follow the ground; False: constant above home, spread reported
    tolerance_m: float = 3.0
    sample_spacing_m: float = 10.0
    max_climb_rate_m_s: float = 3.0
    max_descent_rate_m_s: float = 2.0
    #: Fly at constant altitude even where the terrain opens gaps between the frames.
    accept_overlap_loss: bool = False


@dataclass(frozen=True, kw_only=True)
class MissionSpec:
    name: str
    source: Path  # the TOML file
    area_path: Path
    exclude_paths: tuple[Path, ...]
    camera: Camera
    orientation: Orientation
    survey: SurveySpec
    vehicle: VehicleSpec
    terrain: TerrainSpec | None = None
    #: A corridor survey (planner.corridor): the area file holds the centre line, this is its width.
    corridor_width_m: float | None = None


_TOP_KEYS = {"name", "area", "exclude", "camera", "survey", "vehicle", "terrain", "corridor_width_m"}
_TERRAIN_KEYS = {
    "dem", "follow", "tolerance_m", "sample_spacing_m", "max_climb_rate_m_s", "max_descent_rate_m_s",
    "accept_overlap_loss",
}  # fmt: skip
_SURVEY_KEYS = {
    "gsd_cm", "altitude_agl_m", "front_overlap_pct", "side_overlap_pct", "speed_m_s",
    "direction_deg", "crosshatch", "turnaround_m", "trigger", "oblique", "adjust_speed",
    "max_blur_px", "transit_speed_m_s", "hover_hold_s", "exclusion_clearance_m",
    "oblique_front_overlap_pct", "oblique_side_overlap_pct", "scale", "scale_flight",
}  # fmt: skip
_SCALE_KEYS = {"gsd_cm", "altitude_agl_m", "front_overlap_pct", "side_overlap_pct"}
_OBLIQUE_KEYS = {"tilt_deg", "headings_deg"}
_VEHICLE_KEYS = {
    "type", "home", "home_alt_amsl_m", "takeoff_alt_m", "max_alt_agl_m", "autopilot",
    "climb_rate_m_s", "max_flight_time_min", "endurance_s", "reserve_pct", "reserve_s",
    "battery_capacity_mah", "consumption_ma",
}  # fmt: skip
_FIXED_WING_KEYS = {
    "bank_limit_deg", "airspeed_min_m_s", "airspeed_max_m_s", "takeoff_pitch_deg",
    "landing_glide_slope_deg", "landing_heading_deg",
}  # fmt: skip


def load_spec(path: str | Path) -> MissionSpec:
    """Read and validate a mission spec."""
    file = Path(path)
    if file.is_dir():
        raise SpecError(f"mission spec {file} is a folder; give the spec's .toml file")
    if not file.is_file():
        raise SpecError(f"mission spec {file} does not exist")
    try:
        # utf-8-sig: a byte-order mark some editors (Notepad) put first is read as no character
        data = tomllib.loads(file.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise SpecError(f"{file} is not valid TOML: {error}") from None
    return parse_spec(data, file)


def parse_spec(data: Mapping[str, Any], file: Path) -> MissionSpec:
    """Validate the parsed TOML of a spec; ``file`` anchors relative paths and messages."""
    # Imported here: camera_db loads the camera database, which only specs need.
    from .camera_db import camera_from_mapping

    where = str(file)
    _check_keys(data, _TOP_KEYS, where, "the top level")
    base = file.parent
    name = _get(data, "name", str, where, default=file.stem)
    area_value = _get(data, "area", str, where)
    area_path = (base / area_value).resolve()
    exclude_value = data.get("exclude", [])
    if isinstance(exclude_value, str):
        exclude_value = [exclude_value]
    if not isinstance(exclude_value, list) or not all(isinstance(v, str) for v in exclude_value):
        raise SpecError(f"{where}: exclude must be a list of file names, got {exclude_value!r}")
    exclude_paths = tuple((base / v).resolve() for v in exclude_value)

    camera_data = data.get("camera")
    if not isinstance(camera_data, dict):
        raise SpecError(f'{where}: a [camera] table is required (model = "..." or the sensor fields)')
    camera_fields = dict(camera_data)
    orientation_text = camera_fields.pop("orientation", "landscape")
    orientation = _choice(Orientation, orientation_text, f"{where}: camera.orientation")
    camera = camera_from_mapping(camera_fields, where=f"{where} [camera]")

    survey = _parse_survey(data.get("survey"), where)
    vehicle = _parse_vehicle(data.get("vehicle", {}), where)
    terrain = _parse_terrain(data["terrain"], base, where) if "terrain" in data else None
    corridor_width = _opt_number(data, "corridor_width_m", where, 1.0, 10_000.0)
    return MissionSpec(
        name=name,
        source=file.resolve(),
        area_path=area_path,
        exclude_paths=exclude_paths,
        camera=camera,
        orientation=orientation,
        survey=survey,
        vehicle=vehicle,
        terrain=terrain,
        corridor_width_m=corridor_width,
    )


E = TypeVar("E", bound=StrEnum)


def _choice(choices: type[E], text: Any, key: str) -> E:
    """``text`` as one of the ``choices``; ``key`` names the spec's key ("FILE [survey]: trigger")."""
    try:
        return choices(text)
    except ValueError:
        raise SpecError(f"{key} = {text!r}; use one of {', '.join(c.value for c in choices)}") from None


def _parse_terrain(value: Any, base: Path, where: str) -> TerrainSpec:
    if not isinstance(value, dict):
        raise SpecError(f'{where}: [terrain] must be a table with dem = "file.tif"')
    section = f"{where} [terrain]"
    _check_keys(value, _TERRAIN_KEYS, section, "[terrain]")
    dem = _get(value, "dem", str, section)
    dem_path = (base / dem).resolve()
    if not dem_path.is_file():
        raise SpecError(f"{section}: dem = {dem!r}: {dem_path} does not exist")
    return TerrainSpec(
        dem_path=dem_path,
        follow=_get(value, "follow", bool, section, default=True),
        tolerance_m=_number(value, "tolerance_m", section, 0.5, 100.0, default=3.0),
        sample_spacing_m=_number(value, "sample_spacing_m", section, 1.0, 200.0, default=10.0),
        max_climb_rate_m_s=_number(value, "max_climb_rate_m_s", section, 0.1, 20.0, default=3.0),
        max_descent_rate_m_s=_number(value, "max_descent_rate_m_s", section, 0.1, 20.0, default=2.0),
        accept_overlap_loss=_get(value, "accept_overlap_loss", bool, section, default=False),
    )


def _parse_survey(value: Any, where: str) -> SurveySpec:
    if not isinstance(value, dict):
        raise SpecError(f"{where}: a [survey] table is required (gsd_cm or altitude_agl_m, overlaps)")
    section = f"{where} [survey]"
    _check_keys(value, _SURVEY_KEYS, section, "[survey]")
    gsd = _opt_number(value, "gsd_cm", section, 0.05, 100.0)
    alt = _opt_number(value, "altitude_agl_m", section, 2.0, 5000.0)
    if (gsd is None) == (alt is None):
        raise SpecError(f"{section}: give exactly one of gsd_cm and altitude_agl_m")
    direction: float | None
    raw_direction = value.get("direction_deg", "auto")
    if raw_direction == "auto":
        direction = None
    elif isinstance(raw_direction, int | float) and not isinstance(raw_direction, bool):
        direction = float(raw_direction) % 360.0
    else:
        raise SpecError(f'{section}: direction_deg = {raw_direction!r}; use "auto" or a bearing in degrees')
    trigger_text = value.get("trigger", "distance")
    trigger = _choice(TriggerMode, trigger_text, f"{section}: trigger")
    obliques_raw = value.get("oblique", [])
    if not isinstance(obliques_raw, list):
        raise SpecError(f"{section}: oblique must be an array of tables ([[survey.oblique]])")
    obliques = tuple(_parse_oblique(o, f"{section} oblique {i + 1}") for i, o in enumerate(obliques_raw))
    speed = _number(value, "speed_m_s", section, 0.5, 40.0, default=5.0)
    transit = _opt_number(value, "transit_speed_m_s", section, 0.5, 40.0)
    return SurveySpec(
        gsd_cm=gsd,
        altitude_agl_m=alt,
        front_overlap_pct=_number(value, "front_overlap_pct", section, 0.0, 95.0, default=80.0),
        side_overlap_pct=_number(value, "side_overlap_pct", section, 0.0, 95.0, default=70.0),
        speed_m_s=speed,
        direction_deg=direction,
        crosshatch=_get(value, "crosshatch", bool, section, default=False),
        turnaround_m=_number(value, "turnaround_m", section, 0.0, 500.0, default=10.0),
        trigger=trigger,
        oblique=obliques,
        adjust_speed=_get(value, "adjust_speed", bool, section, default=False),
        max_blur_px=_number(value, "max_blur_px", section, 0.05, 10.0, default=0.5),
        transit_speed_m_s=transit,
        hover_hold_s=_number(value, "hover_hold_s", section, 0.0, 60.0, default=2.0),
        exclusion_clearance_m=_number(value, "exclusion_clearance_m", section, 0.0, 200.0, default=2.0),
        oblique_front_overlap_pct=_opt_number(value, "oblique_front_overlap_pct", section, 0.0, 95.0),
        oblique_side_overlap_pct=_opt_number(value, "oblique_side_overlap_pct", section, 0.0, 95.0),
        scales=_parse_scales(value.get("scale", []), section),
        scale_flight=_parse_scale_flight(value.get("scale_flight", "one_mission"), section),
    )


def _parse_scales(value: Any, section: str) -> tuple[ScaleSpec, ...]:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise SpecError(f"{section}: scale must be an array of tables ([[survey.scale]])")
    out = []
    for i, table in enumerate(value):
        where = f"{section} scale {i + 1}"
        _check_keys(table, _SCALE_KEYS, where, "[[survey.scale]]")
        gsd = _opt_number(table, "gsd_cm", where, 0.05, 100.0)
        alt = _opt_number(table, "altitude_agl_m", where, 2.0, 5000.0)
        if (gsd is None) == (alt is None):
            raise SpecError(f"{where}: give exactly one of gsd_cm and altitude_agl_m")
        out.append(
            ScaleSpec(
                gsd_cm=gsd,
                altitude_agl_m=alt,
                front_overlap_pct=_opt_number(table, "front_overlap_pct", where, 0.0, 95.0),
                side_overlap_pct=_opt_number(table, "side_overlap_pct", where, 0.0, 95.0),
            )
        )
    return tuple(out)


def _parse_scale_flight(value: Any, section: str) -> str:
    if value not in ("one_mission", "sorties"):
        raise SpecError(f'{section}: scale_flight = {value!r}; use "one_mission" or "sorties"')
    return str(value)


def _parse_oblique(value: Any, where: str) -> ObliqueSpec:
    if not isinstance(value, dict):
        raise SpecError(f"{where}: must be a table with tilt_deg and headings_deg")
    _check_keys(value, _OBLIQUE_KEYS, where, "[[survey.oblique]]")
    tilt = _number(value, "tilt_deg", where, 5.0, 60.0)
    headings = value.get("headings_deg", [0, 90, 180, 270])
    if (
        not isinstance(headings, list)
        or not headings
        or not all(isinstance(h, int | float) and not isinstance(h, bool) for h in headings)
    ):
        raise SpecError(f"{where}: headings_deg must be a non-empty list of bearings in degrees")
    return ObliqueSpec(tilt_deg=tilt, headings_deg=tuple(float(h) % 360.0 for h in headings))


def _parse_vehicle(value: Any, where: str) -> VehicleSpec:
    if not isinstance(value, dict):
        raise SpecError(f"{where}: [vehicle] must be a table")
    section = f"{where} [vehicle]"
    _check_keys(value, _VEHICLE_KEYS | _FIXED_WING_KEYS, section, "[vehicle]")
    type_text = value.get("type", "multirotor")
    vehicle_type = _choice(VehicleType, type_text, f"{section}: type")
    autopilot_text = value.get("autopilot", "ardupilot")
    autopilot = _choice(Autopilot, autopilot_text, f"{section}: autopilot")
    home = value.get("home")
    home_lat = home_lon = None
    if home is not None:
        if (
            not isinstance(home, list)
            or len(home) != 2
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in home)
        ):
            raise SpecError(f"{section}: home must be [lat, lon] in degrees, got {home!r}")
        home_lat, home_lon = float(home[0]), float(home[1])
        if not (-90 <= home_lat <= 90 and -180 <= home_lon <= 180):
            raise SpecError(f"{section}: home = {home!r} is not [lat, lon] in degrees")
    max_alt = _number(value, "max_alt_agl_m", section, 1.0, 10000.0, default=120.0)
    takeoff = _number(value, "takeoff_alt_m", section, 1.0, 10000.0, default=30.0)
    if takeoff > max_alt:
        raise SpecError(f"{section}: takeoff_alt_m = {takeoff} is above max_alt_agl_m = {max_alt}; lower it")
    return VehicleSpec(
        **_parse_fixed_wing(value, vehicle_type, section),
        type=vehicle_type,
        home_lat_deg=home_lat,
        home_lon_deg=home_lon,
        home_alt_amsl_m=_number(value, "home_alt_amsl_m", section, -500.0, 9000.0, default=0.0),
        takeoff_alt_m=takeoff,
        max_alt_agl_m=max_alt,
        autopilot=autopilot,
        climb_rate_m_s=_number(value, "climb_rate_m_s", section, 0.2, 20.0, default=2.5),
        max_flight_time_min=_number(
            value,
            "max_flight_time_min",
            section,
            1.0,
            1440.0,
            default=30.0 if vehicle_type is VehicleType.MULTIROTOR else 90.0,
        ),
        endurance_s=_endurance_s(value, section),
        reserve_pct=_number(value, "reserve_pct", section, 0.0, 90.0, default=20.0),
        reserve_s=_number(value, "reserve_s", section, 0.0, 86400.0, default=0.0),
    )


def _endurance_s(value: Mapping[str, Any], section: str) -> float | None:
    """endurance_s, or a battery's capacity over the average current the vehicle draws."""
    endurance = _opt_number(value, "endurance_s", section, 30.0, 86400.0)
    capacity = _opt_number(value, "battery_capacity_mah", section, 10.0, 1.0e6)
    consumption = _opt_number(value, "consumption_ma", section, 10.0, 1.0e6)
    if endurance is not None and (capacity is not None or consumption is not None):
        raise SpecError(
            f"{section}: give either endurance_s or battery_capacity_mah with consumption_ma, not both"
        )
    if (capacity is None) != (consumption is None):
        raise SpecError(
            f"{section}: battery_capacity_mah needs consumption_ma (the average current in flight, mA) "
            f"and the other way round"
        )
    if capacity is not None and consumption is not None:
        endurance = capacity / consumption * 3600.0
        if endurance < 30.0:
            raise SpecError(
                f"{section}: battery_capacity_mah / consumption_ma gives {endurance:.0f} s of flight, "
                f"less than 30 s; check the figures (capacity in mAh, current in mA)"
            )
    return endurance


def _parse_fixed_wing(value: Mapping[str, Any], vehicle_type: VehicleType, section: str) -> dict[str, Any]:
    """The fixed-wing keys of [vehicle] (planner.fixed_wing), refused on other vehicles."""
    given = sorted(set(value) & _FIXED_WING_KEYS)
    if vehicle_type is not VehicleType.FIXED_WING:
        if given:
            raise SpecError(f'{section}: {", ".join(given)} only apply to type = "fixed_wing"; remove them')
        return {}
    from .fixed_wing import check_bank_limit, check_speed_band

    bank = _number(value, "bank_limit_deg", section, -90.0, 90.0, default=30.0)
    check_bank_limit(bank, section)
    low = _number(value, "airspeed_min_m_s", section, 0.0, 100.0, default=9.0)
    high = _number(value, "airspeed_max_m_s", section, 0.0, 100.0, default=22.0)
    check_speed_band(low, high, section)
    heading = _opt_number(value, "landing_heading_deg", section, -360.0, 360.0)
    return {
        "bank_limit_deg": bank,
        "airspeed_min_m_s": low,
        "airspeed_max_m_s": high,
        "takeoff_pitch_deg": _number(value, "takeoff_pitch_deg", section, 5.0, 45.0, default=15.0),
        "landing_glide_slope_deg": _number(value, "landing_glide_slope_deg", section, 2.0, 15.0, default=6.0),
        "landing_heading_deg": None if heading is None else heading % 360.0,
    }


def _check_keys(data: Mapping[str, Any], valid: set[str], where: str, table: str) -> None:
    unknown = sorted(set(data) - valid)
    if unknown:
        raise SpecError(
            f"{where}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} in "
            f"{table}; valid keys: {', '.join(sorted(valid))}"
        )


def _get(data: Mapping[str, Any], key: str, kind: type, where: str, default: Any = ...) -> Any:
    if key not in data:
        if default is ...:
            raise SpecError(f"{where}: {key} is required")
        return default
    value = data[key]
    if (kind is not bool and isinstance(value, bool)) or not isinstance(value, kind):
        raise SpecError(f"{where}: {key} = {value!r} must be a {kind.__name__}")
    return value


def _number(
    data: Mapping[str, Any], key: str, where: str, low: float, high: float, default: Any = ...
) -> float:
    value = _opt_number(data, key, where, low, high)
    if value is None:
        if default is ...:
            raise SpecError(f"{where}: {key} is required ({low:g} to {high:g})")
        return float(default)
    return value


def _opt_number(data: Mapping[str, Any], key: str, where: str, low: float, high: float) -> float | None:
    if key not in data:
        return None
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SpecError(f"{where}: {key} = {value!r} must be a number from {low:g} to {high:g}")
    if not (low <= value <= high):
        raise SpecError(f"{where}: {key} = {value:g} is outside {low:g} to {high:g}")
    return float(value)
