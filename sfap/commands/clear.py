"""``sfap clear``: clear the mission stored on a vehicle, and prove it is empty."""

from __future__ import annotations

from pathlib import Path

import click

from acquisition.transfer import clear_mission

from ..common import echo_json, json_option
from .upload import link_options, open_link


@click.command("clear")
@link_options
@json_option
def command(
    url: str,
    signing_key_file: Path | None,
    require_signing: bool,
    timeout_s: float,
    retries: int,
    heartbeat_timeout_s: float,
    as_json: bool,
) -> None:
    """Clear the mission stored on a vehicle, then read the item count back to confirm.

    Example: sfap clear --connect tcp://127.0.0.1:5760
    """
    with open_link(
        url,
        signing_key_file,
        require_signing,
        heartbeat_timeout_s,
        nothing_sent_note="Nothing was sent: the vehicle's mission is unchanged.",
    ) as link:
        state = clear_mission(link, timeout_s=timeout_s, retries=retries)
        link_url = link.url
    if as_json:
        echo_json({"url": link_url, "state": state.value})
        return
    click.echo(f"{link_url}: {state.sentence}")
