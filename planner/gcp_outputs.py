"""The files of a ground control layout (:mod:`planner.gcp_layout`): GeoJSON, KML, a stake-out
CSV for a GNSS rover, the layout as JSON and a map, written all or nothing."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from xml.sax.saxutils import escape

from .gcp_layout import GcpLayout, GcpOptions, plan_gcps
from .outputs import atomic_write_text, staged_output_dir
from .plan import SurveyPlan

GCP_FILES = ("gcp.geojson", "gcp.kml", "gcp.csv", "gcp.json", "gcp_map.png")


def gcp_geojson(layout: GcpLayout) -> str:
    """The points as a GeoJSON FeatureCollection (WGS84 lon/lat, and their local metres)."""

    features = [
        {
            "type": "Feature",
            "id": p.name,
            "geometry": {"type": "Point", "coordinates": [round(p.lon_deg, 9), round(p.lat_deg, 9)]},
            "properties": {
                "name": p.name,
                "role": p.role,
                "placement": p.placement,
                "lat_deg": p.lat_deg,
                "lon_deg": p.lon_deg,
                "easting_m": p.x_m,
                "northing_m": p.y_m,
                "crs": layout.crs,
                "frame_count": p.frame_count,
            },
        }
        for p in layout.points
    ]
    return json.dumps({"type": "FeatureCollection", "features": features}, indent=1) + "\n"


def gcp_csv(layout: GcpLayout) -> str:
    """For a GNSS rover's stake-out list: name, lat, lon (WGS84 degrees), easting, northing (in
    ``layout.crs``, metres), role."""

    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["name", "lat_deg", "lon_deg", "easting_m", "northing_m", "role", "crs"])
    for p in layout.points:
        writer.writerow(
            [
                p.name,
                f"{p.lat_deg:.9f}",
                f"{p.lon_deg:.9f}",
                f"{p.x_m:.3f}",
                f"{p.y_m:.3f}",
                p.role,
                layout.crs,
            ]
        )
    return buffer.getvalue()


def gcp_kml(layout: GcpLayout, title: str) -> str:
    """The points as KML placemarks (red: control, cyan: check), for a field tablet."""

    marks = []
    for p in layout.points:
        style = "#gcp" if p.role == "gcp" else "#check"
        marks.append(
            f"<Placemark><name>{escape(p.name)}</name><styleUrl>{style}</styleUrl>"
            f"<description>{escape(p.role)} ({escape(p.placement)}), seen by {p.frame_count} planned "
            f"frames; {escape(layout.crs)} E {p.x_m:.3f} N {p.y_m:.3f}</description>"
            f"<Point><coordinates>{p.lon_deg:.9f},{p.lat_deg:.9f},0</coordinates></Point></Placemark>"
        )
    styles = (
        '<Style id="gcp"><IconStyle><color>ff0000ff</color></IconStyle></Style>'
        '<Style id="check"><IconStyle><color>ffffff00</color></IconStyle></Style>'
    )
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2"><Document>'
        f"<name>{escape(title)}: ground control</name>{styles}{''.join(marks)}</Document></kml>\n"
    )


def render_gcp_map(plan: SurveyPlan, layout: GcpLayout, path: str) -> None:
    """The area, its exclusions, the planned frame count as shading, and the points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 8), dpi=100)
    try:
        for poly in getattr(plan.area_xy, "geoms", [plan.area_xy]):
            ax.fill(*poly.exterior.xy, color="#e8f0e0", zorder=0)
            ax.plot(*poly.exterior.xy, color="#3a6b35", lw=1.2)
        for zone in plan.exclusions_xy:
            ax.fill(*zone.exterior.xy, color="#d9534f", alpha=0.4)
        for role, marker, colour in (("gcp", "^", "#c00000"), ("check", "o", "#0070c0")):
            pts = [p for p in layout.points if p.role == role]
            if pts:
                ax.scatter([p.x_m for p in pts], [p.y_m for p in pts], marker=marker, s=70, c=colour,
                           edgecolors="k", zorder=3, label=f"{role} ({len(pts)})")  # fmt: skip
                for p in pts:
                    ax.annotate(p.name, (p.x_m, p.y_m), xytext=(4, 4), textcoords="offset points", fontsize=7)
        ax.set_aspect("equal")
        ax.set_title(f"{plan.name}: ground control ({layout.crs}, metres)", fontsize=9)
        ax.legend(loc="best", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(useOffset=False, style="plain")
        fig.savefig(path, format="png")
    finally:
        plt.close(fig)


def write_gcp_outputs(
    plan: SurveyPlan, layout: GcpLayout, out_dir: str, *, overwrite: bool = False
) -> list[Path]:
    """gcp.geojson, gcp.kml, gcp.csv, gcp.json and gcp_map.png into ``out_dir``, all or nothing."""

    final = Path(out_dir)
    with staged_output_dir(final, overwrite=overwrite) as staging:
        atomic_write_text(staging / "gcp.geojson", gcp_geojson(layout))
        atomic_write_text(staging / "gcp.kml", gcp_kml(layout, plan.name))
        atomic_write_text(staging / "gcp.csv", gcp_csv(layout))
        atomic_write_text(
            staging / "gcp.json", json.dumps(layout.as_dict(), indent=2, allow_nan=False) + "\n"
        )
        render_gcp_map(plan, layout, str(staging / "gcp_map.png"))
    return [final / name for name in GCP_FILES]


def plan_gcp_folder(
    spec_file: str | Path, options: GcpOptions, out_dir: str | Path, *, overwrite: bool = False
) -> tuple[SurveyPlan, GcpLayout]:
    """What ``sfap gcp-plan`` does: plan the survey of the mission spec ``spec_file``, lay out
    its ground control (planner.gcp_layout) and write the files into ``out_dir``."""
    from .spec import load_spec
    from .survey import plan_survey

    plan = plan_survey(load_spec(spec_file))
    layout = plan_gcps(plan, options)
    write_gcp_outputs(plan, layout, str(out_dir), overwrite=overwrite)
    return plan, layout
