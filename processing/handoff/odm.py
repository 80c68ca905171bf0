"""OpenDroneMap project folder, and the Metashape and Pix4D reference files.

ODM: ``images/`` (the frames, hard-linked when the file system allows, else copied),
``geo.txt`` (ODM's image geolocation file: the CRS, then ``name lon lat alt yaw pitch roll
horizontal_accuracy vertical_accuracy``), ``gcp_list.txt`` when control is given (its CRS and
coordinates as surveyed), ``options.json`` (the task options as WebODM, NodeODM and pyodm take
them: a list of {name, value}) and ``odm_args.txt`` (the same as ODM command-line flags).

Options that follow from the data: ``gps-accuracy`` (the median horizontal standard deviation
of the positions), ``camera-lens`` (``brown``: radial and tangential distortion, what a
non-metric frame camera needs), ``matcher-neighbors`` (the 90th percentile of the number of
footprint partners per frame, so a frame is matched against as many as overlap it).
"""

from __future__ import annotations

import json
import math
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from ..gcp import GcpSet
from .block import Block
from .pairs import ImagePairs

GEO_TXT = "geo.txt"
GCP_TXT = "gcp_list.txt"
OPTIONS_JSON = "options.json"


def link_or_copy_images(block: Block, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name in block.names:
        src = block.image_dir / name
        try:
            os.link(src, folder / name)
        except OSError:
            shutil.copy2(src, folder / name)


def odm_options(block: Block, pairs: ImagePairs) -> list[dict[str, Any]]:
    options: list[dict[str, Any]] = [{"name": "camera-lens", "value": "brown"}]
    if block.has_position.any():
        sigma = float(np.median(block.sigma_xy_m[block.has_position]))
        options.append({"name": "gps-accuracy", "value": round(max(sigma, 0.01), 2)})
    partners = (
        np.bincount(np.concatenate([pairs.i, pairs.j]), minlength=len(block)) if len(pairs) else np.zeros(1)
    )
    neighbours = math.ceil(float(np.percentile(partners, 90))) if len(pairs) else 0
    if block.has_position.all() and neighbours > 0:
        options.append({"name": "matcher-neighbors", "value": neighbours})
    return options


def geo_txt(block: Block) -> str | None:
    if not block.has_position.any():
        return None
    yaw = {n: 0.0 for n in block.names}
    pitch = dict(yaw)
    roll = dict(yaw)
    for f in block.frames:
        for k, n in enumerate(f.name):
            yaw[n], pitch[n], roll[n] = float(f.yaw_deg[k]), float(f.pitch_deg[k]), float(f.roll_deg[k])
    lines = ["EPSG:4326"]
    for k, n in enumerate(block.names):
        if block.has_position[k]:
            lines.append(
                f"{n} {block.lon_deg[k]:.8f} {block.lat_deg[k]:.8f} {block.alt_m[k]:.3f} "
                f"{yaw[n]:.2f} {pitch[n]:.2f} "
                f"{roll[n]:.2f} {block.sigma_xy_m[k]:.3f} {block.sigma_z_m[k]:.3f}"
            )
    return "\n".join(lines) + "\n"


def _crs_line(gcps: GcpSet) -> str:
    code = gcps.crs.to_epsg()
    return f"EPSG:{code}" if code else gcps.crs.to_proj4()


def gcp_list_txt(gcps: GcpSet) -> str:
    lines = [_crs_line(gcps)]
    for o in gcps.observations:
        p = gcps.point(o.point)
        lines.append(
            f"{p.source_xy[0]:.4f}\t{p.source_xy[1]:.4f}\t{p.elevation_m:.4f}\t{o.x_px:.2f}\t{o.y_px:.2f}\t{o.image}\t{p.name}"
        )
    return "\n".join(lines) + "\n"


def write_odm_project(block: Block, pairs: ImagePairs, gcps: GcpSet | None, folder: Path) -> dict[str, Any]:
    link_or_copy_images(block, folder / "images")
    geo = geo_txt(block)
    if geo is not None:
        (folder / GEO_TXT).write_text(geo, encoding="utf-8")
    if gcps is not None:
        (folder / GCP_TXT).write_text(gcp_list_txt(gcps), encoding="utf-8")
    options = odm_options(block, pairs)
    (folder / OPTIONS_JSON).write_text(json.dumps(options, indent=2), encoding="utf-8")
    args = " ".join(f"--{o['name']} {o['value']}" for o in options)
    if geo is not None:
        args += " --geo geo.txt"
    if gcps is not None:
        args += " --gcp gcp_list.txt"
    (folder / "odm_args.txt").write_text(args + "\n", encoding="utf-8")
    notes = []
    if geo is None:
        notes.append(
            "no image has a position: no geo.txt (ODM places the model by gcp_list.txt or not at all)"
        )
    return {"options": options, "odm_args": args, "notes": notes}


# --- Metashape and Pix4D ---------------------------------------------------------------------------

_METASHAPE_README = """Metashape reference files written by sfap handoff.

cameras_reference.csv  camera positions: File > Import > Import Reference (or the Reference pane's
                       Import button). Columns: label, longitude, latitude, altitude (m, {alt}),
                       accuracy x/y/z (m), yaw, pitch, roll (deg). Coordinate system WGS 84
                       (EPSG::4326). Angles are the Pix4D/ODM camera convention (yaw = bearing of
                       the image top, pitch = tilt off nadir): leave "Rotation" unticked in the
                       import dialog unless your project uses the same convention.
{gcp}"""

_PIX4D_README = """Pix4D reference files written by sfap handoff.

cameras_pix4d.csv  image geolocation: Project > Image Properties Editor > Image Geolocation >
                   From File..., file format "Latitude, Longitude": columns image name,
                   latitude, longitude, altitude (m, {alt}), horizontal and vertical accuracy
                   (m). Coordinate system WGS 84.
{gcp}"""


def write_reference(block: Block, gcps: GcpSet | None, folder: Path, engine: str) -> dict[str, Any]:
    """``engine``: "metashape" or "pix4d"."""
    alt = block.alt_reference.value if block.alt_reference else "unknown reference"
    yaw: dict[str, tuple[float, float, float]] = {}
    for f in block.frames:
        for k, n in enumerate(f.name):
            yaw[n] = (float(f.yaw_deg[k]), float(f.pitch_deg[k]), float(f.roll_deg[k]))
    rows = []
    for k, n in enumerate(block.names):
        if not block.has_position[k]:
            continue
        y, p, r = yaw.get(n, (0.0, 0.0, 0.0))
        if engine == "metashape":
            rows.append(
                f"{n},{block.lon_deg[k]:.8f},{block.lat_deg[k]:.8f},{block.alt_m[k]:.3f},{block.sigma_xy_m[k]:.3f},"
                f"{block.sigma_xy_m[k]:.3f},{block.sigma_z_m[k]:.3f},{y:.2f},{p:.2f},{r:.2f}"
            )
        else:
            rows.append(
                f"{n},{block.lat_deg[k]:.8f},{block.lon_deg[k]:.8f},{block.alt_m[k]:.3f},{block.sigma_xy_m[k]:.3f},"
                f"{block.sigma_z_m[k]:.3f}"
            )
    gcp_text = ""
    if gcps is not None:
        if engine == "metashape":
            markers = ["label,longitude,latitude,altitude,accuracy"] + [
                f"{p.name},{p.lon_deg:.8f},{p.lat_deg:.8f},{p.elevation_m:.3f},0.02" for p in gcps.points
            ]
            (folder / "markers_reference.csv").write_text("\n".join(markers) + "\n", encoding="utf-8")
            proj = ["marker,image,x_px,y_px"] + [
                f"{o.point},{o.image},{o.x_px:.2f},{o.y_px:.2f}" for o in gcps.observations
            ]
            (folder / "marker_projections.csv").write_text("\n".join(proj) + "\n", encoding="utf-8")
            gcp_text = (
                "markers_reference.csv  ground control as markers: Reference pane > Import (marker "
                "labels, WGS 84).\n"
                "marker_projections.csv where each marker is in each image (pixels from the "
                "top-left corner): place\n"
                "                       each marker on its images (right-click the image > Place "
                "Marker) at these pixels.\n"
            )
        else:
            pts = ["label,latitude,longitude,altitude"] + [
                f"{p.name},{p.lat_deg:.8f},{p.lon_deg:.8f},{p.elevation_m:.3f}" for p in gcps.points
            ]
            (folder / "gcps_pix4d.csv").write_text("\n".join(pts) + "\n", encoding="utf-8")
            marks = [f"{o.image},{o.point},{o.x_px:.2f},{o.y_px:.2f}" for o in gcps.observations]
            (folder / "gcp_image_marks.csv").write_text("\n".join(marks) + "\n", encoding="utf-8")
            gcp_text = (
                "gcps_pix4d.csv       ground control: Project > GCP/MTP Manager > Import GCPs... "
                "(Latitude, Longitude,\n"
                "                     Altitude order: choose 'Lat, Long, Alt').\n"
                "gcp_image_marks.csv  image marks: GCP/MTP Manager > Import Marks... (image, label, "
                "x, y in pixels).\n"
            )
    name = "cameras_reference.csv" if engine == "metashape" else "cameras_pix4d.csv"
    (folder / name).write_text("\n".join(rows) + ("\n" if rows else ""), encoding="utf-8")
    template = _METASHAPE_README if engine == "metashape" else _PIX4D_README
    (folder / "README.txt").write_text(template.format(alt=alt, gcp=gcp_text), encoding="utf-8")
    notes = [] if rows else ["no image has a position: the camera file is empty"]
    return {"files": sorted(p.name for p in folder.iterdir()), "notes": notes}
