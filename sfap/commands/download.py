"""``sfap download``: read the mission stored on a vehicle into a .plan or .waypoints file."""

from __future__ import annotations

from pathlib import Path

import click

from acquisition.transfer import download_mission, downloaded_mission, request_home_position
from planner.errors import InputError, OutputExistsError

from ..common import echo_json, echo_table, json_option, overwrite_option
from .upload import link_options, open_link, progress_bars

_SUFFIXES = (".plan", ".waypoints")


@click.command("download")
@link_options
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="File to write: .plan (QGroundControl) or .waypoints (QGC WPL 110), by its extension.",
)
@overwrite_option
@json_option
def command(
    url: str,
    signing_key_file: Path | None,
    require_signing: bool,
    timeout_s: float,
    retries: int,
    heartbeat_timeout_s: float,
    output: Path,
    overwrite: bool,
    as_json: bool,
) -> None:
    """Download the mission stored on a vehicle to a file; the vehicle is not changed.

    The file's home is the vehicle's home position (HOME_POSITION; ArduPilot's item 0 when
    the vehicle does not send it).

    Example: sfap download --connect tcp://127.0.0.1:5760 -o onboard.plan
    """
    suffix = output.suffix.lower()
    if suffix not in _SUFFIXES:
        raise InputError(f"cannot tell the format of {output}: give -o a name ending in .plan or .waypoints")
    if output.exists() and not overwrite:
        raise OutputExistsError(f"{output} exists; pass --overwrite to replace it")
    with (
        open_link(url, signing_key_file, require_signing, heartbeat_timeout_s) as link,
        progress_bars() as bars,
    ):
        items = download_mission(link, progress=bars, timeout_s=timeout_s, retries=retries)
        home = request_home_position(link, timeout_s=timeout_s)
        autopilot, vehicle_type, link_url = link.autopilot, link.vehicle_type, link.url
    mission = downloaded_mission(items, autopilot, vehicle_type, home=home)
    if suffix == ".plan":
        from planner.formats.qgc_plan import write_plan

        written = write_plan(mission, output, overwrite=overwrite)
    else:
        from planner.formats.waypoints import write_waypoints

        written = write_waypoints(mission, output, overwrite=overwrite)
    summary = {
        "url": link_url,
        "autopilot": autopilot.value,
        "items": len(mission.items),
        "home": {
            "lat_deg": mission.home.lat_deg,
            "lon_deg": mission.home.lon_deg,
            "alt_amsl_m": mission.home.alt_amsl_m,
        },
        "output": str(written),
    }
    if as_json:
        echo_json(summary)
        return
    echo_table(
        [
            ("vehicle", f"{autopilot.value} on {link_url}"),
            ("items", str(len(mission.items))),
            ("written", str(written)),
        ],
        title="Mission downloaded",
    )
