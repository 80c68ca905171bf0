"""The files of a ground control layout (:mod:`planner.gcp_layout`): GeoJSON, KML, a stake-out
CSV for a GNSS rover, the layout as JSON and a map, written all or nothing."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

from .gcp_layout import GcpLayout, GcpOptions, plan_gcps
from .limits import MAX_PHOTOS
from .outputs import atomic_write_bytes, atomic_write_text, staged_output_dir
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


def gcp_map_figure(plan: SurveyPlan, layout: GcpLayout) -> Any:
    """The map of the layout as a matplotlib ``Figure`` (Agg canvas, no pyplot): the area and its
    exclusions (both in the legend), the points with their names, axes labelled in the layout's
    grid (metres), a north arrow (grid north; the caption gives true north) and a scale bar, the
    view fitted to the area with a margin (the figure takes the area's proportions)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import FancyArrow, Patch

    from .maplayout import AREA_EDGE, AREA_FACE, EXCLUSION_COLOUR, caption_text, scale_bar_length_m
    from .mapplot import draw_scale_bar

    x0, y0, x1, y1 = plan.area_xy.bounds
    margin = 0.06 * max(x1 - x0, y1 - y0)
    x0, y0, x1, y1 = x0 - margin, y0 - margin, x1 + margin, y1 + margin
    aspect = (y1 - y0) / (x1 - x0)
    map_w = 7.0
    map_h = min(max(map_w * aspect, 3.0), 9.0)
    if map_w * aspect > map_h:  # a tall area: narrower map
        map_w = map_h / aspect
    legend_w, top, bottom = 2.9, 0.6, 1.0
    fig = Figure(figsize=(map_w + legend_w + 1.2, map_h + top + bottom), dpi=110)
    FigureCanvasAgg(fig)
    width_in, height_in = fig.get_size_inches()
    ax = fig.add_axes((1.0 / width_in, bottom / height_in, map_w / width_in, map_h / height_in))
    for poly in getattr(plan.area_xy, "geoms", [plan.area_xy]):
        ax.fill(*poly.exterior.xy, color=AREA_FACE, zorder=0)
        ax.plot(*poly.exterior.xy, color=AREA_EDGE, lw=1.2, zorder=1)
        for hole in poly.interiors:
            ax.fill(*hole.xy, color="white", zorder=0)
            ax.plot(*hole.xy, color=AREA_EDGE, lw=1.0, zorder=1)
    for zone in plan.exclusions_xy:
        for part in getattr(zone, "geoms", [zone]):
            ax.fill(*part.exterior.xy, facecolor=EXCLUSION_COLOUR, alpha=0.35, edgecolor=EXCLUSION_COLOUR,
                    hatch="//", lw=1.0, zorder=1)  # fmt: skip
    handles: list[Any] = [
        Patch(facecolor=AREA_FACE, edgecolor=AREA_EDGE, label="area to cover"),
    ]
    if plan.exclusions_xy:
        handles.append(
            Patch(
                facecolor=EXCLUSION_COLOUR,
                alpha=0.35,
                edgecolor=EXCLUSION_COLOUR,
                hatch="//",
                label=f"exclusion zones ({len(plan.exclusions_xy)})",
            )
        )
    for role, marker, colour, what in (
        ("gcp", "^", "#c00000", "ground control points"),
        ("check", "o", "#0070c0", "check points"),
    ):
        pts = [p for p in layout.points if p.role == role]
        if not pts:
            continue
        ax.scatter([p.x_m for p in pts], [p.y_m for p in pts], marker=marker, s=70, c=colour,
                   edgecolors="k", zorder=3)  # fmt: skip
        handles.append(Line2D([], [], ls="none", marker=marker, markersize=8, markerfacecolor=colour,
                              markeredgecolor="k", label=f"{what} ({len(pts)})"))  # fmt: skip
        for p in pts:
            ax.annotate(
                p.name, (p.x_m, p.y_m), xytext=(5, 5), textcoords="offset points", fontsize=8, zorder=4
            )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"easting, m ({layout.crs})", fontsize=9)
    ax.set_ylabel(f"northing, m ({layout.crs})", fontsize=9)
    ax.tick_params(labelsize=7)
    ax.ticklabel_format(useOffset=False, style="plain")
    for label in ax.get_yticklabels():
        label.set_rotation(90)
        label.set_verticalalignment("center")
    ax.grid(color="#bdbdbd", lw=0.4, alpha=0.6)
    # north arrow (grid north) beside the map, under the legend; scale bar in the map's corner
    arrow_x = (map_w + 1.6) / width_in
    arrow_top = bottom / height_in + 0.45 * map_h / height_in
    fig.patches.append(
        FancyArrow(
            arrow_x,
            arrow_top - 0.8 / height_in,
            0,
            0.7 / height_in,
            width=0.002,
            head_width=0.12 / width_in,
            head_length=0.18 / height_in,
            length_includes_head=True,
            transform=fig.transFigure,
            color="black",
            figure=fig,
        )
    )
    fig.text(arrow_x, arrow_top - 1.0 / height_in, "N", ha="center", va="center", fontsize=11, weight="bold")
    draw_scale_bar(ax, scale_bar_length_m(x1 - x0), (x0, x1, y0, y1))
    anchor = ((map_w + 1.3) / width_in, 1 - top / height_in)
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=anchor, fontsize=8, frameon=False)
    fig.text(1.0 / width_in, 1 - 0.35 / height_in, f"{plan.name}: ground control", fontsize=12, weight="bold")
    caption = caption_text(plan).replace("metres from home", "metres")
    fig.text(1.0 / width_in, 0.15 / height_in, caption, fontsize=7, color="#424242")
    return fig


def render_gcp_map(plan: SurveyPlan, layout: GcpLayout, path: str) -> None:
    """gcp_map.png of the layout (:func:`gcp_map_figure`)."""
    fig = gcp_map_figure(plan, layout)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    atomic_write_bytes(Path(path), buffer.getvalue())


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
    spec_file: str | Path,
    options: GcpOptions,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    max_photos: int | None = MAX_PHOTOS,
) -> tuple[SurveyPlan, GcpLayout]:
    """What ``sfap gcp-plan`` does: plan the survey of the mission spec ``spec_file`` (refused at
    once beyond ``max_photos`` photos, as ``sfap plan`` does), lay out its ground control
    (planner.gcp_layout) and write the files into ``out_dir``."""
    from .spec import load_spec
    from .survey import plan_survey

    plan = plan_survey(load_spec(spec_file), max_photos=max_photos)
    layout = plan_gcps(plan, options)
    write_gcp_outputs(plan, layout, str(out_dir), overwrite=overwrite)
    return plan, layout
