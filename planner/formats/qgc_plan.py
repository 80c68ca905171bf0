"""QGroundControl ``.plan`` files (JSON), written and read.

The layout follows REFERENCES.md section 4 and QGroundControl's own save and load code
(``src/MissionManager/PlanMasterController.cc`` ``saveToJson``/``loadFromFile``,
``MissionController.cc`` ``save``/``_loadJsonMissionFileV2``, ``MissionItem.cc`` ``save``/``load``,
``SimpleMissionItem.cc`` ``save``, ``TransectStyleComplexItem.cc`` ``_save``/``_load``,
``GeoFenceController.cc``, ``JsonHelper.cc``)::

    {"fileType": "Plan", "version": 1, "groundStation": "...",
     "mission": {"version": 2, "firmwareType": MAV_AUTOPILOT, "vehicleType": MAV_TYPE,
                 "cruiseSpeed": m/s, "hoverSpeed": m/s, "globalPlanAltitudeMode": AltMode,
                 "plannedHomePosition": [lat, lon, alt AMSL], "items": [...]},
     "geoFence": {"version": 2, "circles": [], "polygons": []},
     "rallyPoints": {"version": 2, "points": []}}

A SimpleItem is ``{"type": "SimpleItem", "command", "frame", "autoContinue", "doJumpId",
"params": [p1..p7]}``; NaN is written ``null`` (JSON has no NaN; QGC reads null back as NaN). For
items that fly to a position QGC also writes ``"Altitude"``, ``"AltitudeMode"`` and
``"AMSLAltAboveTerrain"`` (all three or none); sfap writes them the same way.

``doJumpId``: QGC writes each item's sequence number (home is 0, so the first item is 1) and a
DO_JUMP's param1 names the doJumpId of its target. sfap's :class:`~planner.mission.Mission` keeps
DO_JUMP param1 as the 1-based position of the target among the items, which is the same number,
so writing copies it; reading maps doJumpIds back to positions (a real QGC plan may number them
differently, for example after complex items).

Reading also accepts what QGC writes for its survey patterns: a ComplexItem of type ``survey``
(version 4 or 5) or ``CorridorScan`` carries the mission items QGC generated in
``TransectStyleComplexItem.Items``, and those are expanded in place. ``StructureScan`` and the
landing patterns (``fwLandingPattern``, ``vtolLandingPattern``) store only their settings (QGC
regenerates their items when it loads the file), so they are refused with a message, as is any
other complex item type.
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import MissionFileError, MissionValidationError
from ..mission import (
    Autopilot,
    HomePosition,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
    VehicleType,
)
from ..outputs import atomic_write_text
from .mission_file import item_from_params, mav_frame, read_mission_bytes

logger = logging.getLogger(__name__)

PLAN_FILE_TYPE = "Plan"
PLAN_FILE_VERSION = 1  # PlanMasterController kPlanFileVersion
MISSION_VERSION = 2  # MissionController _missionFileVersion
GEOFENCE_VERSION = 2  # GeoFenceController _jsonCurrentVersion
RALLY_VERSION = 2  # RallyPointController _jsonCurrentVersion
GROUND_STATION = "sfap"  # QGC checks only that the key holds a string

# MAV_AUTOPILOT (MAVLink common.xml): QGC writes the number in "firmwareType".
MAV_AUTOPILOT_GENERIC = 0
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
_FIRMWARE_TYPE = {
    Autopilot.ARDUPILOT: MAV_AUTOPILOT_ARDUPILOTMEGA,
    Autopilot.PX4: MAV_AUTOPILOT_PX4,
}

# MAV_TYPE (common.xml). Writing uses what QGC's offline editor uses for each vehicle class
# (AppSettings::offlineEditingVehicleTypeFromVehicleType: quad 2, fixed wing 1, VTOL 20);
# reading groups types as QGCMAVLink::vehicleClass does.
_VEHICLE_TYPE = {VehicleType.MULTIROTOR: 2, VehicleType.FIXED_WING: 1, VehicleType.VTOL: 20}
# quad, coaxial, helicopter, hexa, octo, tri (QGC's list) and dodecarotor (29)
_MULTIROTOR_TYPES = frozenset({2, 3, 4, 13, 14, 15, 29})
_VTOL_TYPES = frozenset({19, 20, 21, 22, 23, 24, 25})
_FIXED_WING_TYPES = frozenset({1})

# QGroundControlQmlGlobal::AltMode
ALT_MODE_MIXED = 0
ALT_MODE_RELATIVE = 1
ALT_MODE_ABSOLUTE = 2
ALT_MODE_CALC_ABOVE_TERRAIN = 3
ALT_MODE_TERRAIN_FRAME = 4
# SimpleMissionItem's frame <-> altitude mode table; other frames get no altitude keys.
_ALT_MODE_BY_FRAME = {
    MavFrame.GLOBAL_RELATIVE_ALT: ALT_MODE_RELATIVE,
    MavFrame.GLOBAL: ALT_MODE_ABSOLUTE,
    MavFrame.GLOBAL_TERRAIN_ALT: ALT_MODE_TERRAIN_FRAME,
}

_TRANSECT_KEY = "TransectStyleComplexItem"
_TRANSECT_ITEMS_KEY = "Items"
_EXPANDABLE_COMPLEX = ("survey", "CorridorScan")
_SETTINGS_ONLY_COMPLEX = {
    "StructureScan": "Structure Scan",
    "fwLandingPattern": "fixed-wing landing pattern",
    "vtolLandingPattern": "VTOL landing pattern",
}


# --- writing ------------------------------------------------------------------------------------


def _json_number(value: float | None, where: str) -> float | None:
    """A number for JSON: None and NaN become null; infinity is refused."""
    if value is None:
        return None
    number = float(value)
    if math.isnan(number):
        return None
    if math.isinf(number):
        raise MissionValidationError(f"{where} is {number}; a mission file needs a finite number")
    return number


def _specifies_altitude(item: MissionItem) -> bool:
    try:
        command = MavCmd(int(item.command))
    except ValueError:
        return False
    return command.is_nav and item.frame in _ALT_MODE_BY_FRAME


def _global_altitude_mode(items: tuple[MissionItem, ...]) -> int:
    modes = {_ALT_MODE_BY_FRAME[item.frame] for item in items if _specifies_altitude(item)}
    if not modes:
        return ALT_MODE_RELATIVE  # QGC's default for a new plan
    if len(modes) == 1:
        return modes.pop()
    return ALT_MODE_MIXED


def _check_jump(item: MissionItem, index: int, count: int) -> None:
    target = item.param1
    if (
        target is None
        or not math.isfinite(target)
        or not float(target).is_integer()
        or not 1 <= target <= count
    ):
        raise MissionValidationError(
            f"item {index} (DO_JUMP): param1 {target} is not the position of an item "
            f"(1-{count}); a DO_JUMP's param1 is the 1-based position of its target"
        )


def plan_document(mission: Mission) -> dict[str, Any]:
    """The mission as a QGC plan document (a dict that ``json.dumps`` turns into the file)."""
    items_json: list[dict[str, Any]] = []
    count = len(mission.items)
    for index, item in enumerate(mission.items, start=1):
        where = f"item {index} ({item.command_name})"
        if int(item.command) == MavCmd.DO_JUMP:
            _check_jump(item, index, count)
        entry: dict[str, Any] = {
            "autoContinue": bool(item.autocontinue),
            "command": int(item.command),
            "doJumpId": index,
            "frame": int(item.frame),
            "params": [_json_number(p, f"{where} param{n}") for n, p in enumerate(item.params, start=1)],
            "type": "SimpleItem",
        }
        if _specifies_altitude(item):
            # As SimpleMissionItem::save: the altitude as entered, its mode, and the terrain
            # height QGC computed (none here: NaN, written null).
            entry["AMSLAltAboveTerrain"] = None
            entry["Altitude"] = _json_number(item.param7, f"{where} altitude")
            entry["AltitudeMode"] = _ALT_MODE_BY_FRAME[item.frame]
        items_json.append(entry)
    home = mission.home
    return {
        "fileType": PLAN_FILE_TYPE,
        "geoFence": {"circles": [], "polygons": [], "version": GEOFENCE_VERSION},
        "groundStation": GROUND_STATION,
        "mission": {
            "cruiseSpeed": _json_number(mission.cruise_speed_m_s, "cruise speed"),
            "firmwareType": _FIRMWARE_TYPE[Autopilot(mission.autopilot)],
            "globalPlanAltitudeMode": _global_altitude_mode(mission.items),
            "hoverSpeed": _json_number(mission.hover_speed_m_s, "hover speed"),
            "items": items_json,
            "plannedHomePosition": [
                _json_number(home.lat_deg, "home latitude"),
                _json_number(home.lon_deg, "home longitude"),
                _json_number(home.alt_amsl_m, "home altitude"),
            ],
            "vehicleType": _VEHICLE_TYPE[VehicleType(mission.vehicle_type)],
            "version": MISSION_VERSION,
        },
        "rallyPoints": {"points": [], "version": RALLY_VERSION},
        "version": PLAN_FILE_VERSION,
    }


def plan_text(mission: Mission) -> str:
    """The .plan file's text: sorted keys (as QGC's QJsonDocument writes them), 4-space indent.

    Floats are written by ``repr``, the shortest text that reads back to the same double, so
    nothing is rounded; ``allow_nan=False`` guarantees strict JSON.
    """
    return json.dumps(plan_document(mission), indent=4, sort_keys=True, allow_nan=False) + "\n"


def write_plan(mission: Mission, path: str | os.PathLike[str], *, overwrite: bool = True) -> Path:
    """Write ``mission`` to ``path`` as a QGC .plan, atomically. Returns the path written."""
    return atomic_write_text(path, plan_text(mission), overwrite=overwrite)


# --- reading ------------------------------------------------------------------------------------


def _as_number(value: object) -> float | None:
    """The value as a float if JSON holds a number there (not a bool), else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _number_or_nan(value: object, where: str, source: str) -> float:
    if value is None:
        return math.nan
    number = _as_number(value)
    if number is None:
        raise MissionFileError(f"{source}: {where} is {value!r}, expected a number or null")
    return number


def _integer(value: object, where: str, source: str) -> int:
    number = _as_number(value)
    if number is None or not number.is_integer():
        raise MissionFileError(f"{source}: {where} is {value!r}, expected an integer")
    return int(number)


def _object(value: object, where: str, source: str) -> Mapping[str, Any]:
    if not isinstance(value, dict):
        raise MissionFileError(f"{source}: {where} is {type(value).__name__}, expected an object")
    return value


def _simple_item(raw: object, where: str, source: str) -> tuple[MissionItem, int | None]:
    """A QGC SimpleItem -> (MissionItem, doJumpId or None)."""
    obj = _object(raw, where, source)
    kind = obj.get("type")
    if kind != "SimpleItem":
        raise MissionFileError(f"{source}: {where} has type {kind!r}, expected 'SimpleItem'")
    for key in ("command", "frame", "params", "autoContinue"):
        if key not in obj:
            raise MissionFileError(f"{source}: {where} has no {key!r} key")
    params = obj["params"]
    if not isinstance(params, list):
        raise MissionFileError(f"{source}: {where} params is not an array")
    if "coordinate" in obj:
        # Plan items before QGC 3.2 kept params 5-7 in "coordinate" (MissionItem V2 -> V3).
        coordinate = obj["coordinate"]
        if not isinstance(coordinate, list) or len(coordinate) != 3:
            raise MissionFileError(f"{source}: {where} coordinate is not [lat, lon, alt]")
        params = [*params, *coordinate]
    if len(params) != 7:
        raise MissionFileError(f"{source}: {where} has {len(params)} params, expected 7 (param1..param7)")
    command = _integer(obj["command"], f"{where} command", source)
    frame_number = _integer(obj["frame"], f"{where} frame", source)
    frame = mav_frame(frame_number)
    if isinstance(frame, str):
        raise MissionFileError(f"{source}: {where} {frame}")
    autocontinue = obj["autoContinue"]
    if not isinstance(autocontinue, bool):
        raise MissionFileError(f"{source}: {where} autoContinue is {autocontinue!r}, expected true or false")
    values = [_number_or_nan(p, f"{where} param{n}", source) for n, p in enumerate(params, start=1)]
    do_jump_id = obj.get("doJumpId")
    jump_id = None if do_jump_id is None else _integer(do_jump_id, f"{where} doJumpId", source)
    item = item_from_params(command, frame, values, autocontinue)
    return item, jump_id


def _complex_items(obj: Mapping[str, Any], where: str, source: str) -> list[tuple[MissionItem, int | None]]:
    """Expand a QGC ComplexItem into the simple items QGC generated and saved with it."""
    complex_type = obj.get("complexItemType")
    if not isinstance(complex_type, str):
        raise MissionFileError(f"{source}: {where} is a ComplexItem with no complexItemType")
    label = f"{where} ({complex_type})"
    if complex_type in _SETTINGS_ONLY_COMPLEX:
        raise MissionFileError(
            f"{source}: {label} is a QGroundControl {_SETTINGS_ONLY_COMPLEX[complex_type]}; QGC "
            f"saves only its settings and regenerates its items on load, so sfap cannot read "
            f"them. Upload this plan with QGroundControl, or replace the pattern with simple items"
        )
    if complex_type not in _EXPANDABLE_COMPLEX:
        raise MissionFileError(
            f"{source}: {where} has complexItemType {complex_type!r}, which sfap does not know; "
            f"it reads {', '.join(repr(t) for t in _EXPANDABLE_COMPLEX)}"
        )
    transect = obj.get(_TRANSECT_KEY)
    generated = transect.get(_TRANSECT_ITEMS_KEY) if isinstance(transect, dict) else None
    if not isinstance(generated, list):
        raise MissionFileError(
            f"{source}: {label} has no {_TRANSECT_KEY}.{_TRANSECT_ITEMS_KEY} (a survey saved by "
            f"QGC before 3.4, version {obj.get('version')!r}); open and save it again in "
            f"QGroundControl"
        )
    return [
        _simple_item(raw, f"{label} generated item {n}", source) for n, raw in enumerate(generated, start=1)
    ]


def _autopilot_from(firmware_type: int, source: str) -> Autopilot:
    if firmware_type == MAV_AUTOPILOT_PX4:
        return Autopilot.PX4
    if firmware_type != MAV_AUTOPILOT_ARDUPILOTMEGA:
        # QGC writes 0 (generic) for plans made with no firmware chosen; the uploader learns
        # the real autopilot from the vehicle's heartbeat anyway.
        logger.warning(
            "%s: firmwareType %d is neither ArduPilot (3) nor PX4 (12); treating the plan as ArduPilot",
            source,
            firmware_type,
        )
    return Autopilot.ARDUPILOT


def _vehicle_type_from(vehicle_type: int | None, source: str) -> VehicleType:
    if vehicle_type is None or vehicle_type in _MULTIROTOR_TYPES:
        return VehicleType.MULTIROTOR
    if vehicle_type in _FIXED_WING_TYPES:
        return VehicleType.FIXED_WING
    if vehicle_type in _VTOL_TYPES:
        return VehicleType.VTOL
    logger.warning(
        "%s: vehicleType %d (MAV_TYPE) is not a multirotor, fixed wing or VTOL; treating it as a multirotor",
        source,
        vehicle_type,
    )
    return VehicleType.MULTIROTOR


def _speed(mission: Mapping[str, Any], key: str, default: float, source: str) -> float:
    if key not in mission or mission[key] is None:
        return default
    value = _as_number(mission[key])
    if value is None or not math.isfinite(value) or value <= 0:
        raise MissionFileError(f"{source}: mission.{key} is {mission[key]!r}, expected a speed in m/s > 0")
    return value


def mission_from_plan_document(document: object, *, source: str = "<plan>") -> Mission:
    """Turn a parsed .plan document (``json.loads`` output) into a :class:`Mission`."""
    root = _object(document, "the document", source)
    file_type = root.get("fileType")
    if file_type != PLAN_FILE_TYPE:
        raise MissionFileError(
            f"{source}: fileType is {file_type!r}, expected {PLAN_FILE_TYPE!r} (a QGroundControl "
            f".plan); QGC's older .mission files and other JSON are not mission plans"
        )
    version = root.get("version")
    if version != PLAN_FILE_VERSION:
        raise MissionFileError(
            f"{source}: plan version is {version!r}, expected {PLAN_FILE_VERSION} (QGroundControl "
            f"3.2 and later)"
        )
    if "mission" not in root:
        raise MissionFileError(f"{source}: the plan has no 'mission' object")
    mission = _object(root["mission"], "mission", source)
    mission_version = mission.get("version", MISSION_VERSION)
    if mission_version != MISSION_VERSION:
        raise MissionFileError(
            f"{source}: mission.version is {mission_version!r}, expected {MISSION_VERSION}; open "
            f"and save the plan again in QGroundControl"
        )
    for key in ("plannedHomePosition", "items", "firmwareType"):
        if key not in mission:
            raise MissionFileError(f"{source}: mission has no {key!r} key, which QGC requires")

    home_raw = mission["plannedHomePosition"]
    if not isinstance(home_raw, list) or len(home_raw) != 3:
        raise MissionFileError(
            f"{source}: mission.plannedHomePosition is {home_raw!r}, expected [lat, lon, alt AMSL]"
        )
    lat, lon, alt = (_number_or_nan(v, f"plannedHomePosition[{k}]", source) for k, v in enumerate(home_raw))
    if math.isnan(lat) or math.isnan(lon):
        raise MissionFileError(f"{source}: plannedHomePosition has no latitude/longitude")
    if math.isnan(alt):
        logger.warning("%s: plannedHomePosition has no altitude; using 0 m AMSL", source)
        alt = 0.0
    home = HomePosition(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)

    firmware_type = _integer(mission["firmwareType"], "mission.firmwareType", source)
    vehicle_raw = mission.get("vehicleType")
    vehicle_type = None if vehicle_raw is None else _integer(vehicle_raw, "mission.vehicleType", source)

    raw_items = mission["items"]
    if not isinstance(raw_items, list):
        raise MissionFileError(f"{source}: mission.items is not an array")
    collected: list[tuple[MissionItem, int | None]] = []
    for n, raw in enumerate(raw_items, start=1):
        where = f"mission item {n}"
        obj = _object(raw, where, source)
        kind = obj.get("type")
        if kind == "SimpleItem":
            collected.append(_simple_item(obj, where, source))
        elif kind == "ComplexItem":
            collected.extend(_complex_items(obj, where, source))
        else:
            raise MissionFileError(
                f"{source}: {where} has type {kind!r}, expected 'SimpleItem' or 'ComplexItem'"
            )

    items = _resolve_jumps(collected, source)

    metadata: dict[str, object] = {
        "source_format": "qgc_plan",
        "source": source,
        "autopilot_from_file": True,
        "qgc_firmware_type": firmware_type,
        "qgc_vehicle_type": vehicle_type,
        "ground_station": root.get("groundStation"),
        "global_plan_altitude_mode": mission.get("globalPlanAltitudeMode"),
    }
    for key in ("geoFence", "rallyPoints"):
        section = root.get(key)
        if isinstance(section, dict) and any(section.get(k) for k in ("circles", "polygons", "points")):
            logger.warning("%s: the plan's %s is kept in metadata, not in the mission", source, key)
            metadata[key] = section
    return Mission(
        items=tuple(items),
        home=home,
        autopilot=_autopilot_from(firmware_type, source),
        vehicle_type=_vehicle_type_from(vehicle_type, source),
        cruise_speed_m_s=_speed(mission, "cruiseSpeed", Mission.cruise_speed_m_s, source),
        hover_speed_m_s=_speed(mission, "hoverSpeed", Mission.hover_speed_m_s, source),
        metadata=metadata,
    )


def _resolve_jumps(collected: list[tuple[MissionItem, int | None]], source: str) -> list[MissionItem]:
    """DO_JUMP param1 holds the target's doJumpId in a plan; make it the target's position."""
    position_by_id: dict[int, int] = {}
    for position, (_item, jump_id) in enumerate(collected, start=1):
        if jump_id is not None:
            position_by_id.setdefault(jump_id, position)
    items: list[MissionItem] = []
    for position, (item, _jump_id) in enumerate(collected, start=1):
        if int(item.command) == MavCmd.DO_JUMP:
            target = item.param1
            if target is None or not float(target).is_integer():
                raise MissionFileError(
                    f"{source}: mission item {position} (DO_JUMP) param1 is {target}, expected "
                    f"the doJumpId of its target"
                )
            if int(target) not in position_by_id:
                raise MissionFileError(
                    f"{source}: mission item {position} (DO_JUMP) jumps to doJumpId "
                    f"{int(target)}, which no item has"
                )
            item = MissionItem(
                command=item.command,
                frame=item.frame,
                param1=float(position_by_id[int(target)]),
                param2=item.param2,
                param3=item.param3,
                param4=item.param4,
                param5=item.param5,
                param6=item.param6,
                param7=item.param7,
                autocontinue=item.autocontinue,
            )
        items.append(item)
    return items


def parse_plan(text: str, *, source: str = "<plan>") -> Mission:
    """Parse the text of a .plan file. Raises :class:`MissionFileError` on anything malformed."""
    if text.startswith("\ufeff"):
        text = text[1:]
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MissionFileError(
            f"{source} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}); a "
            f".plan file is the JSON QGroundControl writes"
        ) from None
    except RecursionError:
        raise MissionFileError(f"{source}: the JSON is nested too deeply to be a plan") from None
    return mission_from_plan_document(document, source=source)


def read_plan(path: str | os.PathLike[str]) -> Mission:
    """Read a QGroundControl .plan file into a :class:`Mission` (survey patterns expanded)."""
    file = Path(path)
    raw = read_mission_bytes(file, ".plan")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise MissionFileError(
            f"{file} is not UTF-8 text, so it is not a QGroundControl .plan (JSON)"
        ) from None
    return parse_plan(text, source=str(file))
