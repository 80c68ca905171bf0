"""OpenDroneMap project folder, and the Metashape and Pix4D reference files.

ODM: ``images/`` (the frames, hard-linked when the file system allows, else copied),
``geo.txt`` (ODM's image geolocation file: the CRS, then ``name lon lat alt yaw pitch roll
horizontal_accuracy vertical_accuracy``), ``gcp_list.txt`` when control is given (its CRS and
coordinates as surveyed), ``options.json`` (the task options as WebODM, NodeODM and pyodm take
them: a list of {name, value}) and ``odm_args.txt`` (the same as ODM command-line flags).

Options that follow from the data: ``camera-lens`` (``brown``: radial and tangential distortion,
what a non-metric frame camera needs) and ``matcher-neighbors`` (the median number of partners a
frame has among the pairs: those its footprint overlaps, or its nearest by position when the
ground is not known; left at ODM's default when that reaches every other frame, since the option
would then match every pair). No ``gps-accuracy``: ODM applies that one number to every image
and so overrides the per-image accuracies of geo.txt (its dataset stage forces the given DOP on
all photos when the option is set), which are what the tags say.
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


def matcher_neighbors(block: Block, pairs: ImagePairs) -> int | None:
    """ODM's ``matcher-neighbors`` from the pairs (module docstring); None: leave ODM's default."""
    if not len(pairs) or not block.has_position.all():
        return None
    partners = np.bincount(np.concatenate([pairs.i, pairs.j]), minlength=len(block))
    neighbours = math.ceil(float(np.median(partners)))
    return neighbours if 0 < neighbours < len(block) - 1 else None


def odm_options(block: Block, pairs: ImagePairs) -> list[dict[str, Any]]:
    options: list[dict[str, Any]] = [{"name": "camera-lens", "value": "brown"}]
    neighbours = matcher_neighbors(block, pairs)
    if neighbours is not None:
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

{cameras}{gcp}"""

_METASHAPE_CAMERAS = """\
cameras_reference.csv  camera positions: File > Import > Import Reference (or the Reference pane's
                       Import button). Columns: label, longitude, latitude, altitude (m, {alt}),
                       accuracy x/y/z (m), yaw, pitch, roll (deg). Coordinate system WGS 84
                       (EPSG::4326). Angles are the Pix4D/ODM camera convention (yaw = bearing of
                       the image top, pitch = tilt off nadir): leave "Rotation" unticked in the
                       import dialog unless your project uses the same convention.
"""

_PIX4D_README = """Pix4D reference files written by sfap handoff (the formats of Pix4D's documentation:
"Image geolocation and orientation import format", "Tie points (GCPs, CPs) import format" and
"How to import and export Tie Points marks"; no header line, commas between columns).

{cameras}{gcp}"""

_PIX4D_CAMERAS = """\
cameras_pix4d.csv  image geolocation and orientation: PIX4Dmatic File > Import image geolocations
                   and orientations... (PIX4Dmapper: Image Properties Editor > Image Geolocation >
                   From File...). Nine columns: image name, latitude, longitude (WGS 84, EPSG:4326,
                   in its axis order), altitude (m, {alt}), yaw, pitch, roll (deg, Pix4D's
                   convention), horizontal and vertical accuracy (m).
"""

#: The accuracy written for each image mark of a Pix4D marks file, pixels: a mark placed by hand on
#: a target's centre (the GCP files carry no accuracy of their marks).
MARK_ACCURACY_PX = 1.0


def _unknown_heights_note(gcps: GcpSet) -> str:
    return (
        "The ground control's elevations are all 0.0 in "
        f"{Path(gcps.source).name}, OpenDroneMap's mark for an unknown height: the altitude cells are\n"
        "left empty (Metashape: the marker has no Z reference; Pix4D: set these points' type to 2D GCP,\n"
        "PIX4Dmapper GCP/MTP Manager, or give their heights before processing). The files hold no\n"
        "accuracy of the survey either: set the marker accuracy (Metashape Reference Settings) or the\n"
        "GCP accuracy (Pix4D) to what the survey achieved.\n"
    )


def _metashape_gcps(gcps: GcpSet, folder: Path, known: bool) -> str:
    markers = ["label,longitude,latitude,altitude"] + [
        f"{p.name},{p.lon_deg:.8f},{p.lat_deg:.8f}," + (f"{p.elevation_m:.3f}" if known else "")
        for p in gcps.points
    ]
    (folder / "markers_reference.csv").write_text("\n".join(markers) + "\n", encoding="utf-8")
    proj = ["marker,image,x_px,y_px"] + [
        f"{o.point},{o.image},{o.x_px:.2f},{o.y_px:.2f}" for o in gcps.observations
    ]
    (folder / "marker_projections.csv").write_text("\n".join(proj) + "\n", encoding="utf-8")
    return (
        "markers_reference.csv  ground control as markers: Reference pane > Import (marker labels, WGS 84;\n"
        "                       the first line names the columns: start from line 2). No accuracy\n"
        "                       column: the GCP file gives none.\n"
        "marker_projections.csv where each marker is in each image (pixels from the top-left corner): place\n"
        "                       each marker on its images (right-click the image > Place Marker) at these\n"
        "                       pixels.\n"
    )


def _pix4d_gcps(gcps: GcpSet, folder: Path, known: bool) -> str:
    pts = [
        f"{p.name},{p.lat_deg:.8f},{p.lon_deg:.8f}," + (f"{p.elevation_m:.3f}" if known else "")
        for p in gcps.points
    ]
    (folder / "gcps_pix4d.csv").write_text("\n".join(pts) + "\n", encoding="utf-8")
    marks = [f"{o.image},{o.point},{o.x_px:.2f},{o.y_px:.2f},{MARK_ACCURACY_PX:g}" for o in gcps.observations]
    (folder / "gcp_image_marks.csv").write_text("\n".join(marks) + "\n", encoding="utf-8")
    return (
        "gcps_pix4d.csv       ground control: PIX4Dmatic File > Import GCPs... (PIX4Dmapper: GCP/MTP\n"
        "                     Manager > Import GCPs..., order Latitude, Longitude, Altitude). Four\n"
        "                     columns: label, latitude, longitude (WGS 84), altitude (m); no accuracy\n"
        "                     columns: the GCP file gives none, so Pix4D's default accuracy applies until\n"
        "                     you set the survey's.\n"
        "gcp_image_marks.csv  image marks: image name, point label, x, y (pixels from the top-left corner),\n"
        f"                     accuracy (pixels, {MARK_ACCURACY_PX:g}: a mark placed by hand on a target's\n"
        "                     centre).\n"
    )


def write_reference(block: Block, gcps: GcpSet | None, folder: Path, engine: str) -> dict[str, Any]:
    """``engine``: "metashape" or "pix4d". No camera file when no image has a position (the
    result's ``complete`` is then False: the hand-off could not give what was asked)."""
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
                f"{n},{block.lat_deg[k]:.8f},{block.lon_deg[k]:.8f},{block.alt_m[k]:.3f},{y:.2f},{p:.2f},{r:.2f},"
                f"{block.sigma_xy_m[k]:.3f},{block.sigma_z_m[k]:.3f}"
            )
    notes: list[str] = []
    gcp_text = ""
    if gcps is not None:
        known = any(p.elevation_m != 0.0 for p in gcps.points)
        gcp_text = (_metashape_gcps if engine == "metashape" else _pix4d_gcps)(gcps, folder, known)
        if not known:
            gcp_text += "\n" + _unknown_heights_note(gcps)
            notes.append(
                "the ground control's elevations are all 0.0 (unknown): written without heights and without "
                "accuracies (README.txt)"
            )
    name = "cameras_reference.csv" if engine == "metashape" else "cameras_pix4d.csv"
    cameras_text = ""
    if rows:
        (folder / name).write_text("\n".join(rows) + "\n", encoding="utf-8")
        cameras_text = (_METASHAPE_CAMERAS if engine == "metashape" else _PIX4D_CAMERAS).format(alt=alt)
    else:
        cameras_text = f"{name} is not written: no image has a position.\n"
    template = _METASHAPE_README if engine == "metashape" else _PIX4D_README
    (folder / "README.txt").write_text(template.format(cameras=cameras_text, gcp=gcp_text), encoding="utf-8")
    files = sorted(p.name for p in folder.iterdir())
    if not rows:
        notes.append(
            f"no image has a position: {name} (the camera positions) was not written; written: "
            + ", ".join(files)
        )
    return {"files": files, "notes": notes, "complete": bool(rows)}
