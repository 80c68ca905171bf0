"""Loading and validating survey areas: GeoJSON and KML polygons (and corridor centre lines) in
WGS84.

An area file holds one or more polygons (holes allowed). The area to survey is their union;
holes are excluded, and so are the extra exclusion polygons a spec lists. A corridor's area
file holds one LineString, its centre line (:func:`load_centreline`). Every problem is
reported with the file name and the fix, never as a shapely or JSON traceback.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.validation import explain_validity

from .errors import AreaError

#: Plausible limits for one survey area (square metres): a house plot to a large block.
MIN_AREA_M2 = 25.0
MAX_AREA_M2 = 2_500e6  # 2,500 km2
_CRS84_NAMES = {
    "urn:ogc:def:crs:OGC:1.3:CRS84",
    "urn:ogc:def:crs:OGC::CRS84",
    "urn:ogc:def:crs:EPSG::4326",
    "EPSG:4326",
    "epsg:4326",
}


def load_polygons(path: str | Path) -> list[Polygon]:
    """Every polygon in a GeoJSON (.geojson/.json) or KML (.kml) file, lon/lat degrees."""
    file = Path(path)
    if file.is_dir():
        raise AreaError(f"area file {file} is a folder; give the polygon's file (GeoJSON or KML) in the spec")
    if not file.is_file():
        raise AreaError(f"area file {file} does not exist; check the path in the mission spec")
    suffix = file.suffix.lower()
    if suffix in (".geojson", ".json"):
        polygons = _polygons_from_geojson(file)
    elif suffix == ".kml":
        polygons = _polygons_from_kml(file)
    else:
        raise AreaError(
            f"area file {file}: unknown format {suffix!r}; give a GeoJSON (.geojson) or KML (.kml) "
            f"polygon in WGS84"
        )
    if not polygons:
        if _holds_lines(file):
            raise AreaError(
                f"area file {file} holds a line, not a polygon: for a corridor along it set "
                f"corridor_width_m in the spec; for a block draw the survey area as a Polygon"
            )
        raise AreaError(f"area file {file} holds no polygon; draw the survey area as a Polygon")
    for polygon in polygons:
        _check_polygon(polygon, file)
    return polygons


def _holds_lines(file: Path) -> bool:
    """Whether the area file holds a LineString (a corridor's centre line given as a block's area)."""
    try:
        if file.suffix.lower() == ".kml":
            return any(True for _ in _iter_local(_read_kml(file), "LineString"))
        return bool(
            _geojson_geometries(_read_geojson(file, "the area"), ("LineString", "MultiLineString"), file)
        )
    except AreaError:
        return False


def _check_ring(coords: Sequence[Sequence[float]], file: Path, what: str) -> list[tuple[float, float]]:
    points: list[tuple[float, float]] = []
    for position in coords:
        if not isinstance(position, list | tuple) or len(position) < 2:
            raise AreaError(f"{file}: {what} has a position {position!r} that is not [lon, lat]")
        lon, lat = float(position[0]), float(position[1])
        if not (math.isfinite(lon) and math.isfinite(lat)):
            raise AreaError(f"{file}: {what} has a non-finite coordinate {position!r}")
        points.append((lon, lat))
    if len(points) < 4:
        raise AreaError(
            f"{file}: {what} has {len(points)} positions; a closed ring needs at least 4 (three "
            f"corners and the first repeated at the end)"
        )
    if points[0] != points[-1]:
        raise AreaError(
            f"{file}: {what} is not closed (first position {points[0]} differs from the last "
            f"{points[-1]}); repeat the first position at the end"
        )
    for lon, lat in points:
        if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            raise AreaError(
                f"{file}: {what} has coordinate ({lon}, {lat}) outside longitude -180..180 / latitude "
                f"-90..90: the file looks projected (metres); export it in WGS84 (EPSG:4326)"
            )
    return points


def _read_geojson(file: Path, what: str) -> dict[str, Any]:
    """A GeoJSON file's top object, refusing a CRS other than WGS84 lon/lat (RFC 7946)."""
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise AreaError(f"{file} is not valid GeoJSON: {error}") from None
    if not isinstance(data, dict):
        raise AreaError(f"{file} is not a GeoJSON object")
    crs = data.get("crs")
    if isinstance(crs, dict):
        name = str(crs.get("properties", {}).get("name", ""))
        if name and name not in _CRS84_NAMES:
            raise AreaError(
                f"{file} declares CRS {name!r}; sfap reads WGS84 lon/lat (RFC 7946): re-export "
                f"{what} in EPSG:4326"
            )
    return data


def _polygons_from_geojson(file: Path) -> list[Polygon]:
    geometries = _geojson_geometries(_read_geojson(file, "the area"), ("Polygon", "MultiPolygon"), file)
    polygons: list[Polygon] = []
    for k, geometry in enumerate(geometries):
        kind = geometry.get("type")
        coords = geometry.get("coordinates")
        if kind == "Polygon":
            polygons.append(_polygon_from_rings(coords, file, f"polygon {k + 1}"))
        elif kind == "MultiPolygon":
            for j, rings in enumerate(coords or []):
                polygons.append(_polygon_from_rings(rings, file, f"polygon {k + 1}.{j + 1}"))
    return polygons


def _geojson_geometries(node: Any, kinds: tuple[str, ...], file: Path) -> list[dict[str, Any]]:
    """Every geometry of one of ``kinds`` in a GeoJSON object, through collections and features."""
    out: list[dict[str, Any]] = []

    def walk(node: Any) -> None:
        if not isinstance(node, dict):
            return
        kind = node.get("type")
        if kind == "FeatureCollection":
            for feature in node.get("features") or []:
                walk(feature)
        elif kind == "Feature":
            walk(node.get("geometry"))
        elif kind == "GeometryCollection":
            for geometry in node.get("geometries") or []:
                walk(geometry)
        elif kind in kinds:
            out.append(node)
        elif kind is None:
            raise AreaError(f"{file}: a GeoJSON object has no 'type'")

    walk(node)
    return out


def _polygon_from_rings(rings: Any, file: Path, what: str) -> Polygon:
    if not isinstance(rings, list) or not rings:
        raise AreaError(f"{file}: {what} has no coordinates")
    shell = _check_ring(rings[0], file, f"{what} exterior ring")
    holes = [_check_ring(r, file, f"{what} hole {i + 1}") for i, r in enumerate(rings[1:])]
    return Polygon(shell, holes)


def _read_kml(file: Path) -> ET.Element:
    try:
        return ET.parse(file).getroot()
    except ET.ParseError as error:
        raise AreaError(f"{file} is not valid KML: {error}") from None


def _polygons_from_kml(file: Path) -> list[Polygon]:
    root = _read_kml(file)
    polygons = []
    for k, element in enumerate(_iter_local(root, "Polygon")):
        what = f"polygon {k + 1}"
        outer = [b for b in element if _local(b.tag) == "outerBoundaryIs"]
        if not outer:
            raise AreaError(f"{file}: {what} has no outerBoundaryIs")
        shell = _check_ring(_kml_ring(outer[0], file, what), file, f"{what} outer boundary")
        holes = [
            _check_ring(_kml_ring(b, file, what), file, f"{what} inner boundary {i + 1}")
            for i, b in enumerate(b for b in element if _local(b.tag) == "innerBoundaryIs")
        ]
        polygons.append(Polygon(shell, holes))
    return polygons


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _iter_local(root: ET.Element, name: str) -> Iterable[ET.Element]:
    return (e for e in root.iter() if _local(e.tag) == name)


def _kml_ring(boundary: ET.Element, file: Path, what: str) -> list[list[float]]:
    """The positions of the first <coordinates> below ``boundary`` (lon,lat[,alt] each)."""
    text = next((e.text for e in _iter_local(boundary, "coordinates")), None)
    if not text or not text.strip():
        raise AreaError(f"{file}: {what} has an empty <coordinates>")
    ring: list[list[float]] = []
    for token in text.split():
        try:
            ring.append([float(v) for v in token.split(",")])
        except ValueError:
            raise AreaError(f"{file}: {what} has a bad coordinate {token!r}") from None
    return ring


def _check_polygon(polygon: Polygon, file: Path) -> None:
    if polygon.is_empty:
        raise AreaError(f"{file}: a polygon is empty")
    xy = np.asarray(polygon.exterior.coords)
    span = xy - xy[0]
    cross = span[1:, 0] * span[:-1, 1] - span[1:, 1] * span[:-1, 0]
    if np.all(np.abs(cross) < 1e-18):
        raise AreaError(f"{file}: a polygon is empty (all its corners on a line)")
    if not polygon.is_valid:
        reason = explain_validity(polygon)
        raise AreaError(
            f"{file}: polygon is invalid ({reason}); fix the self-intersection or crossing rings "
            f"in a GIS (QGIS: Vector > Geometry Tools > Check Validity)"
        )


def build_area(
    polygons: Sequence[Polygon], exclusions: Sequence[Polygon]
) -> tuple[Polygon | MultiPolygon, tuple[Polygon, ...]]:
    """The area to survey (union minus holes minus exclusions) and every excluded zone.

    Works in whatever coordinates it is given (lon/lat or metres). Excluded zones are the
    holes of the area polygons plus the explicit exclusions, merged where they touch.
    """
    union = shapely.union_all([shapely.Polygon(p.exterior) for p in polygons])
    holes = [Polygon(ring) for p in polygons for ring in p.interiors]
    excluded = shapely.union_all([*holes, *exclusions]) if (holes or exclusions) else None
    area = union.difference(excluded) if excluded is not None else union
    area = shapely.make_valid(area)
    area = polygonal(area)
    zones: tuple[Polygon, ...] = ()
    if excluded is not None:
        zones = (
            tuple(polygonal(shapely.make_valid(excluded)).geoms)
            if not isinstance(excluded, Polygon)
            else (excluded,)
        )
    return area, zones


def polygon_parts(geom: shapely.Geometry) -> list[Polygon]:
    """The non-empty polygons of any geometry (collections and multi-parts flattened)."""
    if geom.is_empty:
        return []
    if isinstance(geom, Polygon):
        return [geom]
    out: list[Polygon] = []
    for g in getattr(geom, "geoms", []):
        out.extend(polygon_parts(g))
    return out


def polygonal(geom: shapely.Geometry) -> MultiPolygon:
    """The polygons of ``geom`` as one valid MultiPolygon: an intersection or make_valid can
    return pieces that overlap or touch along an edge (an invalid MultiPolygon, which GEOS then
    refuses), so those are merged."""
    parts = polygon_parts(geom)
    if not parts:
        return MultiPolygon()
    merged = MultiPolygon(parts)
    if not merged.is_valid:
        merged = MultiPolygon(polygon_parts(shapely.make_valid(shapely.union_all(parts))))
    return merged


def check_area_size(area_m2: float, where: str) -> None:
    """Refuse areas too small or too large to be a drone survey."""
    if area_m2 < MIN_AREA_M2:
        raise AreaError(
            f"{where}: the area to survey is {area_m2:.1f} m2 after exclusions, below "
            f"{MIN_AREA_M2:.0f} m2; check the polygon (degrees in the right order: lon, lat)"
        )
    if area_m2 > MAX_AREA_M2:
        raise AreaError(
            f"{where}: the area is {area_m2 / 1e6:.0f} km2, above {MAX_AREA_M2 / 1e6:.0f} km2 "
            f"for one survey; split it into several missions"
        )


def load_centreline(path: str | Path) -> list[tuple[float, float]]:
    """The centre line of a corridor: the one LineString of a GeoJSON or KML file, lon/lat."""
    file = Path(path)
    if not file.is_file():
        raise AreaError(f"corridor centre line {file} does not exist; check the area path in the spec")
    suffix = file.suffix.lower()
    lines: list[Any]
    if suffix in (".geojson", ".json"):
        lines = []
        data = _read_geojson(file, "the centre line")
        for geometry in _geojson_geometries(data, ("LineString", "MultiLineString"), file):
            coords = geometry.get("coordinates") or []
            lines.extend([coords] if geometry.get("type") == "LineString" else coords)
    elif suffix == ".kml":
        root = _read_kml(file)
        lines = [_kml_ring(line, file, "the centre line") for line in _iter_local(root, "LineString")]
    else:
        raise AreaError(
            f"corridor centre line {file}: unknown format {suffix!r}; give a GeoJSON (.geojson) or "
            f"KML (.kml) LineString in WGS84"
        )
    if len(lines) != 1:
        raise AreaError(
            f"{file} holds {len(lines)} LineStrings; a corridor's area file holds exactly one, its "
            f"centre line (corridor_width_m is set in the spec)"
        )
    points: list[tuple[float, float]] = []
    for position in lines[0]:
        if not isinstance(position, list | tuple) or len(position) < 2:
            raise AreaError(f"{file}: the centre line has a position {position!r} that is not [lon, lat]")
        lon, lat = float(position[0]), float(position[1])
        if not (math.isfinite(lon) and math.isfinite(lat) and -180 <= lon <= 180 and -90 <= lat <= 90):
            raise AreaError(
                f"{file}: the centre line has a position ({lon}, {lat}) outside WGS84 lon/lat; export "
                f"it in EPSG:4326"
            )
        if not points or (lon, lat) != points[-1]:
            points.append((lon, lat))
    if len(points) < 2:
        raise AreaError(f"{file}: the centre line has fewer than two distinct positions; draw the corridor")
    return points
