"""KML 2.2 of a :class:`~planner.plan.SurveyPlan`, for Google Earth and other viewers.

One ``Document`` with a ``LookAt`` on the area, shared styles, and folders in this order:

- Area: the area polygon (holes as inner boundaries) and every exclusion zone as a separate
  red polygon, clamped to the ground;
- Flight path: the path the vehicle flies, from the mission's own positional items
  (take-off, waypoints, return to launch), as a 3D ``LineString``;
- Survey lines: one sub-folder per pass, one ``LineString`` per camera-on segment;
- Stations: one ``Point`` per exposure, every k-th only when there are more than
  ``max_stations`` (the folder's description says so and how many are shown);
- Home (and the entry of the first line) placemarks.

Altitudes. Mission altitudes are relative to HOME, which KML cannot express. When the home
altitude above mean sea level is known, everything airborne is written with
``altitudeMode`` ``absolute`` at home AMSL + altitude above home, which is exact whatever the
terrain. Otherwise it is written ``relativeToGround`` at the altitude above home, which is
exact only where the ground is as high as home; the document's description says so.
Google Earth draws ``absolute`` altitudes above its geoid (EGM96), the same reference as
``alt_amsl_m``.
"""

from __future__ import annotations

import copy
import logging
import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from ..errors import InputError
from ..kinds import PassKind
from ..mission import MavCmd, MavFrame
from ..outputs import atomic_write_bytes
from ..plan import SurveyPlan
from ..stats import median

log = logging.getLogger(__name__)

KML_NS = "http://www.opengis.net/kml/2.2"

#: Stations drawn as points at most; Google Earth slows down past a few thousand placemarks.
DEFAULT_MAX_STATIONS = 2000

_ICONS = "http://maps.google.com/mapfiles/kml/shapes/"

# KML colours are aabbggrr.
_LINE_COLOURS = {
    PassKind.NADIR: "ffffa000",  # blue
    PassKind.CROSSHATCH: "ffff00c0",  # purple
    PassKind.OBLIQUE: "ff0080ff",  # orange
}

_RELATIVE_FRAMES = frozenset({MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT})
_AMSL_FRAMES = frozenset({MavFrame.GLOBAL, MavFrame.GLOBAL_INT})
_TERRAIN_FRAMES = frozenset({MavFrame.GLOBAL_TERRAIN_ALT, MavFrame.GLOBAL_TERRAIN_ALT_INT})
_LAND_COMMANDS = frozenset({MavCmd.NAV_LAND, MavCmd.NAV_VTOL_LAND})


def _q(tag: str) -> str:
    return f"{{{KML_NS}}}{tag}"


def _sub(parent: ET.Element, tag: str, text: str | None = None) -> ET.Element:
    element = ET.SubElement(parent, _q(tag))
    if text is not None:
        element.text = text
    return element


@dataclass(frozen=True, kw_only=True)
class _Altitudes:
    """How airborne altitudes are written: the KML mode and the offset added to alt above home."""

    mode: str  # "absolute" or "relativeToGround"
    offset_m: float  # home AMSL for "absolute", 0 otherwise
    note: str

    def of(self, alt_rel_home_m: float) -> float:
        return self.offset_m + alt_rel_home_m


def _altitudes(home_alt_amsl_m: float | None) -> _Altitudes:
    if home_alt_amsl_m is not None:
        return _Altitudes(
            mode="absolute",
            offset_m=home_alt_amsl_m,
            note=(
                f"Altitudes: absolute (above mean sea level) = home {home_alt_amsl_m:.1f} m AMSL "
                f"+ mission altitude above home."
            ),
        )
    return _Altitudes(
        mode="relativeToGround",
        offset_m=0.0,
        note=(
            "Altitudes: the home altitude above sea level is unknown, so the mission's altitudes "
            "above HOME are drawn above the ground below each point; they are right only where "
            "the ground is as high as home."
        ),
    )


def _coords(points: Iterable[Sequence[float]]) -> str:
    return " ".join(f"{p[0]:.8f},{p[1]:.8f},{p[2]:.2f}" for p in points)


def _ring2d(coords: Iterable[Sequence[float]]) -> str:
    return " ".join(f"{c[0]:.8f},{c[1]:.8f},0" for c in coords)


def _placemark(parent: ET.Element, name: str, style: str, description: str | None = None) -> ET.Element:
    # KML 2.2 order inside a Feature: name, ..., description, ..., styleUrl, ..., Geometry
    mark = _sub(parent, "Placemark")
    _sub(mark, "name", name)
    if description:
        _sub(mark, "description", description)
    _sub(mark, "styleUrl", f"#{style}")
    return mark


def _folder(parent: ET.Element, name: str, description: str | None = None) -> ET.Element:
    folder = _sub(parent, "Folder")
    _sub(folder, "name", name)
    if description:
        _sub(folder, "description", description)
    return folder


def _polygon(parent: ET.Element, poly: Polygon) -> None:
    poly = orient(poly, sign=1.0)  # KML wants outer rings counter-clockwise
    element = _sub(parent, "Polygon")
    _sub(element, "tessellate", "1")
    _sub(element, "altitudeMode", "clampToGround")
    outer = _sub(_sub(element, "outerBoundaryIs"), "LinearRing")
    _sub(outer, "coordinates", _ring2d(poly.exterior.coords))
    for interior in poly.interiors:
        inner = _sub(_sub(element, "innerBoundaryIs"), "LinearRing")
        _sub(inner, "coordinates", _ring2d(interior.coords))


def _polygons(parent: ET.Element, geom: Polygon | MultiPolygon) -> None:
    parts = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    parts = [p for p in parts if not p.is_empty]
    if len(parts) == 1:
        _polygon(parent, parts[0])
        return
    multi = _sub(parent, "MultiGeometry")
    for part in parts:
        _polygon(multi, part)


def _line_string(parent: ET.Element, points: Sequence[Sequence[float]], mode: str) -> None:
    element = _sub(parent, "LineString")
    _sub(element, "altitudeMode", mode)
    _sub(element, "coordinates", _coords(points))


def _point(parent: ET.Element, lon: float, lat: float, alt: float, mode: str) -> None:
    element = _sub(parent, "Point")
    _sub(element, "altitudeMode", mode)
    _sub(element, "coordinates", _coords([(lon, lat, alt)]))


def _style(
    doc: ET.Element,
    style_id: str,
    *,
    line: tuple[str, float] | None = None,
    poly: str | None = None,
    icon: tuple[str, float, str] | None = None,
    label_scale: float | None = None,
) -> None:
    # Style children in schema order: IconStyle, LabelStyle, LineStyle, PolyStyle
    style = _sub(doc, "Style")
    style.set("id", style_id)
    if icon is not None:
        href, scale, colour = icon
        icon_style = _sub(style, "IconStyle")
        _sub(icon_style, "color", colour)
        _sub(icon_style, "scale", f"{scale:g}")
        _sub(_sub(icon_style, "Icon"), "href", href)
    if label_scale is not None:
        _sub(_sub(style, "LabelStyle"), "scale", f"{label_scale:g}")
    if line is not None:
        line_style = _sub(style, "LineStyle")
        _sub(line_style, "color", line[0])
        _sub(line_style, "width", f"{line[1]:g}")
    if poly is not None:
        poly_style = _sub(style, "PolyStyle")
        _sub(poly_style, "color", poly)


def mission_track(
    plan: SurveyPlan, home_alt_amsl_m: float | None = None
) -> tuple[list[tuple[float, float, float]], bool]:
    """The flown path from the mission's positional items: (lon deg, lat deg, alt above home m).

    Starts and ends on the ground at home; a take-off or waypoint at 0, 0 (PX4, ArduPilot:
    "here") stays where the vehicle is; return to launch goes home at the last altitude, then
    down. Returns the points and whether any item flies above terrain (then its altitude is
    above ground, not above home). ``home_alt_amsl_m`` turns items given above sea level into
    altitudes above home (default: the plan's home altitude when known).
    """
    home = plan.home
    home_amsl = _home_amsl(plan) if home_alt_amsl_m is None else home_alt_amsl_m
    points = [(home.lon_deg, home.lat_deg, 0.0)]
    terrain = False
    for item in plan.mission.items:
        try:
            command = MavCmd(int(item.command))
        except ValueError:
            continue
        if command is MavCmd.NAV_RETURN_TO_LAUNCH:
            points.append((home.lon_deg, home.lat_deg, points[-1][2]))
            points.append((home.lon_deg, home.lat_deg, 0.0))
            continue
        if not command.is_nav or not item.frame.is_global:
            continue
        lon, lat = item.lon_deg, item.lat_deg
        if lat == 0.0 and lon == 0.0:
            lon, lat = points[-1][0], points[-1][1]
        alt = item.alt_m
        if item.frame in _AMSL_FRAMES:
            alt = alt - (home_amsl or 0.0)
        elif item.frame in _TERRAIN_FRAMES:
            terrain = True
        if command in _LAND_COMMANDS:
            alt = 0.0
        points.append((lon, lat, alt))
    if len(points) < 3 and len(plan.path_lonlat_deg) >= 2:
        # a mission without positional items: fall back on the planned path at survey height
        alt = median(plan.stations.alt_rel_home_m) if len(plan.stations) else 0.0
        points = [(float(lon), float(lat), alt) for lon, lat in plan.path_lonlat_deg]
    return points, terrain


def _home_amsl(plan: SurveyPlan) -> float | None:
    # HomePosition defaults alt_amsl_m to 0.0 when nobody knew it; a home exactly at sea
    # level is treated as unknown too, which only changes the altitude mode.
    value = getattr(plan.home, "alt_amsl_m", None)
    if value is None or value == 0.0 or not math.isfinite(value):
        return None
    return float(value)


def thin_step(n: int, max_count: int) -> int:
    """Keep every ``thin_step``-th of ``n`` items so that at most ``max_count`` remain (>= 1)."""
    return 1 if n <= max_count or max_count <= 0 else -(-n // max_count)


def ordinal(k: int) -> str:
    """1st, 2nd, 3rd, 4th, ..., 11th, 12th, 13th, ..., 21st."""
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def kml_document(
    plan: SurveyPlan,
    *,
    max_stations: int = DEFAULT_MAX_STATIONS,
    home_alt_amsl_m: float | None = None,
) -> ET.Element:
    """The KML tree of ``plan`` (see :func:`write_kml`)."""
    if home_alt_amsl_m is None:
        home_alt_amsl_m = _home_amsl(plan)
    track, terrain = mission_track(plan, home_alt_amsl_m)
    alts = _altitudes(home_alt_amsl_m)
    path_alts = alts
    if terrain:
        path_alts = _Altitudes(
            mode="relativeToGround",
            offset_m=0.0,
            note="The mission flies above terrain: its path is drawn above the ground.",
        )
    s = plan.summary
    st = plan.stations

    root = ET.Element(_q("kml"))
    doc = _sub(root, "Document")
    _sub(doc, "name", plan.name)
    _sub(doc, "open", "1")
    _sub(
        doc,
        "description",
        f"sfap survey plan: GSD {s.gsd_cm:.2f} cm at {s.altitude_agl_m:.1f} m above ground, "
        f"{s.line_count} lines, {s.photo_count} photos, camera {s.camera_id}. "
        f"{alts.note}" + (f" {path_alts.note}" if terrain else ""),
    )
    minx, miny, maxx, maxy = plan.area_xy.bounds
    centre_lon, centre_lat = plan.frame.to_lonlat((minx + maxx) / 2, (miny + maxy) / 2)
    look = _sub(doc, "LookAt")
    _sub(look, "longitude", f"{float(centre_lon):.8f}")
    _sub(look, "latitude", f"{float(centre_lat):.8f}")
    _sub(look, "altitude", "0")
    _sub(look, "heading", "0")
    _sub(look, "tilt", "0")
    _sub(look, "range", f"{max(200.0, 1.6 * math.hypot(maxx - minx, maxy - miny)):.0f}")
    _sub(look, "altitudeMode", "relativeToGround")

    _style(doc, "area", line=("ff32a02e", 2), poly="3332a02e")
    _style(doc, "exclusion", line=("ff0000ff", 2), poly="800000ff")
    _style(doc, "path", line=("ff00ffff", 2))
    for kind, colour in _LINE_COLOURS.items():
        _style(doc, f"line-{kind.value}", line=(colour, 3))
    _style(doc, "station", icon=(_ICONS + "shaded_dot.png", 0.4, "ffffffff"), label_scale=0)
    _style(doc, "home", icon=(_ICONS + "homegardenbusiness.png", 1.2, "ffffffff"))
    _style(doc, "entry", icon=(_ICONS + "flag.png", 1.0, "ff00ff00"))

    area_folder = _folder(doc, "Area")
    mark = _placemark(
        area_folder,
        "Survey area",
        "area",
        f"{s.area_m2:.0f} m2 to cover, holes and exclusion zones removed.",
    )
    _polygons(mark, plan.area_lonlat)
    for k, zone in enumerate(plan.exclusions_lonlat):
        mark = _placemark(area_folder, f"Exclusion {k + 1}", "exclusion", "No photos, no transit.")
        _polygons(mark, zone)

    path_folder = _folder(doc, "Flight path", path_alts.note)
    mark = _placemark(
        path_folder,
        "Flight path",
        "path",
        f"{s.flight_distance_m / 1000:.2f} km, about {s.flight_time_s / 60:.0f} min, take-off to return.",
    )
    _line_string(mark, [(lon, lat, path_alts.of(alt)) for lon, lat, alt in track], path_alts.mode)

    lines_folder = _folder(doc, "Survey lines", "Camera-on segments, first to last photo.")
    line_alt = _line_altitudes(plan)
    for p in plan.passes:
        pass_folder = _folder(
            lines_folder,
            f"Pass {p.index}: {p.name}",
            f"{len(p.lines)} lines, {p.alt_agl_m:.1f} m above ground, tilt {p.tilt_deg:g} deg, "
            f"trigger every {p.trigger_distance_m:.2f} m.",
        )
        if not p.lines:
            continue
        ends = np.array([(ln.start_xy_m, ln.end_xy_m) for ln in p.lines], dtype=float)
        lon, lat = plan.frame.to_lonlat(ends[..., 0].ravel(), ends[..., 1].ravel())
        lon, lat = lon.reshape(-1, 2), lat.reshape(-1, 2)
        for k, ln in enumerate(p.lines):
            alt = alts.of(line_alt.get((p.index, ln.line_index), p.alt_agl_m))
            mark = _placemark(
                pass_folder,
                f"Pass {p.index} line {ln.line_index}",
                f"line-{p.kind.value}",
                f"heading {ln.heading_deg:.1f} deg, {ln.length_m:.1f} m",
            )
            _line_string(mark, [(lon[k, 0], lat[k, 0], alt), (lon[k, 1], lat[k, 1], alt)], alts.mode)

    step = thin_step(len(st), max_stations)
    shown = np.arange(0, len(st), step) if max_stations > 0 else np.zeros(0, dtype=np.int64)
    if len(shown) == len(st):
        about = f"All {len(st)} exposure stations."
    else:
        about = (
            f"Every {ordinal(step)} of the {len(st)} exposure stations in flight order "
            f"({len(shown)} shown); stations.geojson holds all of them."
        )
    stations_folder = _folder(doc, "Stations", about)
    for k in shown.tolist():
        mark = _placemark(
            stations_folder,
            f"{k}",
            "station",
            f"pass {st.pass_index[k]} line {st.line_index[k]}; "
            f"{st.alt_rel_home_m[k]:.1f} m above home, {st.alt_agl_m[k]:.1f} m above ground; "
            f"heading {st.heading_deg[k]:.1f} deg, looking {st.look_heading_deg[k]:.1f} deg, "
            f"tilt {st.tilt_deg[k]:.1f} deg; GSD {st.gsd_cm[k]:.2f} cm",
        )
        _point(
            mark,
            float(st.lon_deg[k]),
            float(st.lat_deg[k]),
            alts.of(float(st.alt_rel_home_m[k])),
            alts.mode,
        )

    home = plan.home
    mark = _placemark(
        doc,
        "Home",
        "home",
        "Take-off and return."
        + (f" {home_alt_amsl_m:.1f} m above sea level." if home_alt_amsl_m is not None else ""),
    )
    _point(mark, home.lon_deg, home.lat_deg, 0.0, "clampToGround")
    if plan.passes and plan.passes[0].lines:
        first = plan.passes[0].lines[0]
        elon, elat = plan.frame.to_lonlat(*first.entry_xy_m)
        mark = _placemark(
            doc, "Entry", "entry", f"Start of the first line, heading {first.heading_deg:.1f} deg."
        )
        _point(mark, float(elon), float(elat), 0.0, "clampToGround")
    return root


def _line_altitudes(plan: SurveyPlan) -> dict[tuple[int, int], float]:
    """Mean altitude above home of the stations of each (pass, line)."""
    st = plan.stations
    if len(st) == 0:
        return {}
    keys = st.pass_index.astype(np.int64) * (int(st.line_index.max()) + 1) + st.line_index
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    sums = np.bincount(inverse, weights=st.alt_rel_home_m)
    counts = np.bincount(inverse)
    return {
        (int(st.pass_index[i]), int(st.line_index[i])): float(total / count)
        for i, total, count in zip(first, sums, counts, strict=True)
    }


def kml_bytes(
    plan: SurveyPlan,
    *,
    max_stations: int = DEFAULT_MAX_STATIONS,
    home_alt_amsl_m: float | None = None,
) -> bytes:
    """The KML document of ``plan`` as UTF-8 bytes with an XML declaration."""
    root = kml_document(plan, max_stations=max_stations, home_alt_amsl_m=home_alt_amsl_m)
    text = serialise(root)
    return b"<?xml version='1.0' encoding='utf-8'?>\n" + text.encode("utf-8") + b"\n"


def serialise(root: ET.Element) -> str:
    """``root`` as ElementTree writes it indented by one space with KML as the default
    namespace (``ET.indent(root, space=" ")``, then ``ET.tostring(root, encoding="unicode")``),
    the same text, in a third of the time: every tag of this document is in KML's namespace,
    and no element has a tail before indenting, so the general writer's namespace pass and
    checks are not needed. A tree outside that (or an attribute that would need escaping) is
    handed to ElementTree itself. ``root`` is left as it was (not indented)."""
    prefix = f"{{{KML_NS}}}"
    cut = len(prefix)
    parts: list[str] = []
    write = parts.append

    def element(elem: ET.Element, indent: str, declaration: str = "") -> bool:
        tag = elem.tag
        if not isinstance(tag, str) or not tag.startswith(prefix) or elem.tail:
            return False
        name = tag[cut:]
        write("<" + name + declaration)
        for key, value in elem.items():
            plain = isinstance(key, str) and isinstance(value, str) and key[:1] != "{"
            if not plain or _NEEDS_ESCAPE.search(value):
                return False
            write(f' {key}="{value}"')
        text = elem.text
        if text is not None and not isinstance(text, str):
            return False
        if len(elem):
            inner = indent + " "
            write(">" + (_escape_text(text) if text and text.strip() else inner))
            last = len(elem) - 1
            for k, child in enumerate(elem):
                if not element(child, inner):
                    return False
                write(indent if k == last else inner)
            write("</" + name + ">")
        elif text:
            write(">" + _escape_text(text) + "</" + name + ">")
        else:
            write(" />")
        return True

    if len(root) and element(root, "\n", f' xmlns="{KML_NS}"'):
        return "".join(parts)
    ET.register_namespace("", KML_NS)
    indented = copy.deepcopy(root)
    ET.indent(indented, space=" ")
    return ET.tostring(indented, encoding="unicode")


_NEEDS_ESCAPE = re.compile('[&<>"\r\n\t]')


def _escape_text(text: str) -> str:
    """Character data as ElementTree escapes it (&, < and >)."""
    if "&" in text:
        text = text.replace("&", "&amp;")
    if "<" in text:
        text = text.replace("<", "&lt;")
    if ">" in text:
        text = text.replace(">", "&gt;")
    return text


def write_kml(
    plan: SurveyPlan,
    path: str | os.PathLike[str],
    *,
    max_stations: int = DEFAULT_MAX_STATIONS,
    home_alt_amsl_m: float | None = None,
) -> Path:
    """Write ``plan`` as a KML 2.2 document (mission.kml) that opens in Google Earth, atomically.

    ``max_stations``: exposure stations drawn as points at most (every k-th beyond, and
    the Stations folder says so). ``home_alt_amsl_m``: home altitude above mean sea level, m;
    when None, ``plan.home.alt_amsl_m`` is used unless it is 0 (unknown). With it, airborne
    altitudes are ``absolute``; without, ``relativeToGround`` (see the module docstring).
    Returns the path written.
    """
    if max_stations < 0:
        raise InputError(f"max_stations = {max_stations} must be 0 or more")
    data = kml_bytes(plan, max_stations=max_stations, home_alt_amsl_m=home_alt_amsl_m)
    written = atomic_write_bytes(path, data)
    log.debug("wrote KML: %s (%d bytes)", written, len(data))
    return written
