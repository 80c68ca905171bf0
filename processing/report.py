"""The check's report folder: one page a person reads on a laptop in the field, and its data.

Files (written together, all or nothing, by :func:`write_report`):

- report.html: the verdict first (pass or fail, with the reasons), the key figures, four maps
  (views per cell, gaps, GSD, base-height ratio), the gaps table and the flagged frames; it
  loads the PNGs next to it, nothing from the network.
- view_count.png, gaps.png, gsd.png, base_height.png: the maps (:mod:`processing.report_maps`).
- report.json: the same figures for programs (:meth:`CheckResult.as_dict`).
- coverage.tif: views per cell (GeoTIFF, the check's UTM CRS; opens in QGIS).
- gaps.geojson: one polygon per gap (WGS84), with its index and area.
- footprints.geojson: one polygon per frame (WGS84), with its name, height and GSD.

"""

from __future__ import annotations

import html
import json
import logging
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import Polygon, mapping
from shapely.geometry.polygon import orient

from planner.outputs import atomic_write_bytes, atomic_write_text, json_safe, staged_output_dir
from planner.plan import SurveyPlan

from .check_result import CheckResult
from .distribution import Distribution
from .report_maps import base_height_png, gaps_png, gsd_png, view_count_png

log = logging.getLogger(__name__)

REPORT_FILES = (
    "report.html",
    "report.json",
    "coverage.tif",
    "gaps.geojson",
    "footprints.geojson",
    "view_count.png",
    "gaps.png",
    "gsd.png",
    "base_height.png",
)

# --- vector files ----------------------------------------------------------------------------


def _feature_collection(name: str, features: Sequence[dict[str, Any]]) -> str:
    return (
        json.dumps({"type": "FeatureCollection", "name": name, "features": list(features)}, allow_nan=False)
        + "\n"
    )


def _rounded(geom: Polygon) -> dict[str, Any]:
    ring = orient(geom, sign=1.0)
    data: dict[str, Any] = mapping(ring)
    data["coordinates"] = [[[round(x, 8), round(y, 8)] for x, y in r] for r in data["coordinates"]]
    return data


def gaps_geojson(result: CheckResult) -> str:
    """One Polygon feature per gap (WGS84 lon/lat), properties ``gap`` (index) and ``area_m2``."""
    return _feature_collection(
        "gaps",
        [
            {
                "type": "Feature",
                "geometry": _rounded(g.polygon_lonlat),
                "properties": {"gap": g.index, "area_m2": round(g.area_m2, 2)},
            }
            for g in result.gaps
        ],
    )


def footprints_geojson(result: CheckResult) -> str:
    """One Polygon feature per frame (WGS84), properties ``name``, ``height_agl_m``, ``gsd_cm``."""
    features = []
    rings = result.footprints_lonlat
    for k, name in enumerate(result.frames.name):
        ring = np.vstack([rings[k], rings[k][:1]])
        poly = Polygon(ring)
        if poly.is_empty or poly.area == 0:
            continue
        gsd = float(result.gsd_cm[k])
        features.append(
            {
                "type": "Feature",
                "geometry": _rounded(poly),
                "properties": {
                    "name": name,
                    "height_agl_m": round(float(result.height_agl_m[k]), 2),
                    "gsd_cm": round(gsd, 3) if math.isfinite(gsd) else None,
                },
            }
        )
    return _feature_collection("footprints", features)


def report_json(result: CheckResult) -> str:
    """report.json: :meth:`CheckResult.as_dict` with NaN as null."""
    return json.dumps(json_safe(result.as_dict()), indent=2, allow_nan=False) + "\n"


# --- the page ------------------------------------------------------------------------------------

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 62em; color: #212121;
       padding: 0 1em; line-height: 1.4; }
.verdict { padding: 0.8em 1.2em; border-radius: 6px; color: white; margin-bottom: 1em; }
.verdict h1 { margin: 0; font-size: 2em; }
.pass { background: #2e7d32; } .fail { background: #c62828; }
.verdict ul { margin: 0.4em 0 0 0; font-size: 1.05em; }
.warn { background: #fff8e1; border-left: 5px solid #f9a825; padding: 0.5em 1em; margin: 1em 0; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; }
td, th { border-bottom: 1px solid #e0e0e0; padding: 0.25em 0.8em; text-align: left;
         vertical-align: top; }
th { background: #f5f5f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.maps { display: grid; grid-template-columns: repeat(auto-fit, minmax(28em, 1fr)); gap: 1em; }
.maps img { width: 100%; border: 1px solid #e0e0e0; }
.small { color: #616161; font-size: 0.9em; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _table(headers: Sequence[str], rows: Sequence[Sequence[object]], numeric: Sequence[bool] = ()) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = []
    for row in rows:
        cells = []
        for k, value in enumerate(row):
            cls = ' class="num"' if k < len(numeric) and numeric[k] else ""
            cells.append(f"<td{cls}>{_e(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _dist_row(label: str, dist: Distribution | None, fmt: str, unit: str) -> list[object]:
    if dist is None:
        return [label, "-", "-", "-", "-", "-", 0]
    return [
        label,
        *(f"{getattr(dist, k):{fmt}}{unit}" for k in ("min", "p10", "median", "p90", "max")),
        dist.count,
    ]


def report_html(result: CheckResult, *, refly: SurveyPlan | None = None) -> str:
    """The page (see the module docstring); PNGs are referenced by file name."""
    verdict = "PASS" if result.passed else "FAIL"
    cls = "pass" if result.passed else "fail"
    title = f"sfap check: {verdict}"
    if result.plan is not None:
        title += f" - {result.plan.planned.name}"
    reasons = "".join(f"<li>{_e(r)}</li>" for r in result.reasons)
    verdict_html = (
        f'<div class="verdict {cls}"><h1>{verdict}</h1>'
        + (f"<ul>{reasons}</ul>" if reasons else "<div>every threshold is met</div>")
        + "</div>"
    )
    warnings = "".join(f"<li>{_e(w)}</li>" for w in result.warnings)
    warn_html = f'<div class="warn"><b>Warnings</b><ul>{warnings}</ul></div>' if warnings else ""
    figures = _table(["figure", "value"], result.key_figures())
    coverage_rows = [
        [f">= {k} frame{'s' if k > 1 else ''}", f"{v:.1f} %"] for k, v in result.seen_pct.items()
    ]
    coverage = _table(["share of the area seen by", ""], coverage_rows, numeric=[False, True])
    dists = _table(
        ["distribution", "min", "10 %", "median", "90 %", "max", "count"],
        [
            _dist_row("forward overlap", result.stereo.forward_overlap_pct, ".0f", " %"),
            _dist_row("side overlap", result.stereo.side_overlap_pct, ".0f", " %"),
            _dist_row("B/H, consecutive frames of a line", result.base_height_along_line, ".2f", ""),
            _dist_row("B/H, neighbouring lines", result.base_height_across_lines, ".2f", ""),
            _dist_row(
                "B/H, every overlapping pair",
                Distribution.of(result.stereo.pair_base_height_ratio),
                ".2f",
                "",
            ),
            _dist_row(
                "pair intersection angle",
                Distribution.of(result.stereo.pair_intersection_deg),
                ".1f",
                " deg",
            ),
            _dist_row("GSD", Distribution.of(result.gsd_cm), ".2f", " cm"),
            _dist_row("height above ground", Distribution.of(result.height_agl_m), ".1f", " m"),
            _dist_row(
                "ground speed",
                Distribution.of(result.stereo.speed_m_s) if result.stereo.speed_m_s is not None else None,
                ".1f",
                " m/s",
            ),
            _dist_row(
                "motion blur",
                Distribution.of(result.stereo.blur_px) if result.stereo.blur_px is not None else None,
                ".2f",
                " px",
            ),
        ],
        numeric=[False, True, True, True, True, True, True],
    )
    if result.gaps:
        gap_rows = [
            [g.index, f"{g.area_m2:,.0f}", f"{g.centroid_lat_deg:.6f}", f"{g.centroid_lon_deg:.6f}"]
            for g in result.gaps
        ]
        gaps = _table(
            ["gap", "area m2", "centre lat deg", "centre lon deg"],
            gap_rows,
            [True, True, True, True],
        )
    else:
        gaps = "<p>No gap: every part of the area is seen by at least one frame.</p>"
    if result.flagged:
        flagged = _table(["frame", "flag", "detail"], [[f.name, f.kind, f.detail] for f in result.flagged])
    else:
        flagged = "<p>No frame flagged.</p>"
    if result.left_out:
        left_out = "<h2>Frames left out</h2>" + _table(
            ["frame", "why"], [list(item) for item in result.left_out]
        )
    else:
        left_out = ""
    notes = "".join(f"<li>{_e(n)}</li>" for n in result.notes)
    thresholds = ", ".join(f"{k} = {v:g}" for k, v in result.thresholds.as_dict().items())
    refly_html = ""
    if refly is not None:
        su = refly.summary
        refly_html = (
            "<h2>Re-fly mission</h2>"
            f"<p>refly/mission.plan (QGroundControl) and refly/mission.waypoints: {su.photo_count} photos "
            f"on {su.line_count} line(s) at {su.altitude_agl_m:.1f} m above ground, "
            f"{su.flight_distance_m:,.0f} m, about {su.flight_time_s / 60:.0f} min; map in "
            "refly/map.png.</p>"
        )
    maps = "".join(
        f'<figure><img src="{name}" alt="{_e(alt)}"></figure>'
        for name, alt in (
            ("view_count.png", "views per ground cell"),
            ("gaps.png", "gaps"),
            ("gsd.png", "ground sample distance"),
            ("base_height.png", "base-height ratio"),
        )
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_e(title)}</title><style>{_CSS}</style></head>
<body>
{verdict_html}
{warn_html}
<h2>Key figures</h2>
{figures}
<h2>Maps</h2>
<div class="maps">{maps}</div>
<h2>Coverage</h2>
{coverage}
<h2>Gaps</h2>
{gaps}
<p class="small">Polygons in gaps.geojson; views per cell in coverage.tif (open both in QGIS).</p>
<h2>Overlap, stereo, GSD and blur</h2>
{dists}
{refly_html}
<h2>Flagged frames</h2>
{flagged}
{left_out}
<h2>How this was computed</h2>
<ul><li>ground: {_e(result.ground_description)}</li><li>area: {_e(result.area_source)}</li>
{notes}</ul>
<p class="small">Thresholds: {_e(thresholds)}.
Full figures in report.json.</p>
</body></html>
"""


#: coverage.tif's value outside the area judged (0 inside means no frame sees the cell).
COVERAGE_NODATA = -1


def write_coverage_tif(result: CheckResult, path: str | os.PathLike[str]) -> Path:
    """coverage.tif: frames that see each cell, int32, ``COVERAGE_NODATA`` outside the area, in
    the UTM zone's EPSG code when the area lies in one zone (resampled, nearest, same cell size),
    else in the check's own transverse Mercator frame; the band is described."""
    from .geotiff import write_geotiff

    counts = np.where(result.in_area, result.view_count, COVERAGE_NODATA).astype(np.int32)
    _, crs = result.output_crs()  # the one CRS report.json names too
    return write_geotiff(
        path,
        counts,
        result.grid,
        nodata=COVERAGE_NODATA,
        description="views: frames that see the cell (0 = gap; nodata outside the area judged)",
        to_crs=None if crs == result.frame.crs else crs,
    )


def write_report(
    result: CheckResult,
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    refly: SurveyPlan | None = None,
) -> list[Path]:
    """Write every report file (module docstring) into ``out_dir``, all or nothing; with
    ``refly``, that mission's files (``sfap plan``'s set) into ``out_dir/refly``."""
    from planner.plan_folder import OUTPUT_FILES, write_outputs

    final = Path(out_dir)
    with staged_output_dir(final, overwrite=overwrite) as staging:
        atomic_write_bytes(staging / "view_count.png", view_count_png(result))
        atomic_write_bytes(staging / "gaps.png", gaps_png(result))
        atomic_write_bytes(staging / "gsd.png", gsd_png(result))
        atomic_write_bytes(staging / "base_height.png", base_height_png(result))
        write_coverage_tif(result, staging / "coverage.tif")
        atomic_write_text(staging / "gaps.geojson", gaps_geojson(result))
        atomic_write_text(staging / "footprints.geojson", footprints_geojson(result))
        atomic_write_text(staging / "report.json", report_json(result))
        atomic_write_text(staging / "report.html", report_html(result, refly=refly))
        if refly is not None:
            write_outputs(refly, staging / "refly")
    written = [final / name for name in REPORT_FILES]
    if refly is not None:
        written += [final / "refly" / name for name in OUTPUT_FILES]
    return written
