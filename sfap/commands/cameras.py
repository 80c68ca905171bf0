"""`sfap cameras`: list the built-in camera database, or show one camera's derived figures."""

from __future__ import annotations

import click

from planner.camera import Camera
from planner.camera_db import get_camera, load_cameras
from planner.camera_figures import CameraFigures, camera_figures, camera_row

from ..common import echo_json, echo_table, json_option

#: Height above ground at which `sfap cameras ID` shows GSD and footprint, metres.
_SHOW_HEIGHT_AGL_M = 100.0
#: GSDs for which `sfap cameras ID` gives the flying height, centimetres.
_SHOW_GSD_CM = (1.0, 2.0, 3.0)


def _echo_list(cameras: list[Camera]) -> None:
    header = ("id", "name", "sensor mm", "image px", "focal mm", "pitch um")
    lines = [
        (
            camera.id,
            camera.name,
            f"{camera.sensor_width_mm:g} x {camera.sensor_height_mm:g}",
            f"{camera.image_width_px} x {camera.image_height_px}",
            f"{camera.focal_length_mm:g}",
            f"{max(camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm) * 1000:.2f}",
        )
        for camera in cameras
    ]
    widths = [max(len(cells[i]) for cells in (header, *lines)) for i in range(len(header))]
    for cells in (header, *lines):
        padded = (cell.ljust(width) for cell, width in zip(cells, widths, strict=True))
        click.echo("  ".join(padded).rstrip())


def _echo_show(figures: CameraFigures) -> None:
    camera = figures.camera
    height = f"{figures.alt_agl_m:g} m AGL"
    shutter = "unknown" if camera.shutter_s is None else f"{camera.shutter_s:g} s"
    rows: list[tuple[str, str]] = [
        ("name", camera.name),
        ("sensor", f"{camera.sensor_width_mm:g} x {camera.sensor_height_mm:g} mm"),
        ("image", f"{camera.image_width_px} x {camera.image_height_px} px"),
        (
            "focal length",
            f"{camera.focal_length_mm:g} mm ({figures.focal_length_35mm_equiv_mm:.1f} mm 35 mm-equivalent)",
        ),
        (
            "pixel pitch x / y",
            f"{figures.pixel_pitch_x_um:.3f} / {figures.pixel_pitch_y_um:.3f} um",
        ),
        (
            "field of view x / y / diagonal",
            f"{figures.fov_x_deg:.1f} / {figures.fov_y_deg:.1f} / {figures.fov_diagonal_deg:.1f} deg",
        ),
        ("min trigger interval", f"{camera.min_trigger_interval_s:g} s"),
        ("shutter (blur check)", shutter),
        ("EXIF make / model", f"{camera.exif_make} / {camera.exif_model}"),
        (f"GSD x / y at {height}", f"{figures.gsd_x_cm:.3f} / {figures.gsd_y_cm:.3f} cm"),
        (
            f"footprint at {height}",
            f"{figures.footprint_width_m:.1f} x {figures.footprint_height_m:.1f} m (image width x height)",
        ),
        (f"scale at {height}", f"1:{figures.scale_number:.0f}"),
    ]
    rows += [
        (f"height for {gsd_cm:g} cm GSD", f"{alt_agl_m:.1f} m AGL")
        for gsd_cm, alt_agl_m in figures.heights_for_gsd
    ]
    rows.append(("source", camera.source))
    echo_table(rows, title=camera.id)


@click.command("cameras")
@click.argument("camera_id", required=False, metavar="[ID]")
@json_option
def command(camera_id: str | None, as_json: bool) -> None:
    """List the built-in cameras, or show one camera's derived figures.

    Without ID: one line per camera with its id (what a mission spec's [camera] model takes),
    name, sensor size (mm), image size (px), real focal length (mm, not 35 mm-equivalent) and
    pixel pitch (um).

    With ID: pixel pitch per axis, field of view, GSD and footprint at 100 m above ground level
    over flat ground, the flying height (m AGL) for 1, 2 and 3 cm GSD, EXIF make and model, and
    the source of the numbers.

    Example: sfap cameras dji-phantom-4-pro --json
    """
    if camera_id is None:
        cameras = list(load_cameras().values())
        if as_json:
            echo_json([camera_row(camera) for camera in cameras])
        else:
            _echo_list(cameras)
        return
    figures = camera_figures(
        get_camera(camera_id), height_agl_m=_SHOW_HEIGHT_AGL_M, gsd_targets_cm=_SHOW_GSD_CM
    )
    if as_json:
        echo_json(figures.to_dict())
    else:
        _echo_show(figures)
