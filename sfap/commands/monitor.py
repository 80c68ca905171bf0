"""``sfap monitor``: record camera events and telemetry during a flight, with a live status line."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from acquisition.monitor import MonitorResult, StopReason, monitor
from acquisition.monitor_state import MonitorState
from acquisition.signing import load_signing_key
from planner.outputs import check_output_dir, check_writable

from ..common import FiniteFloatRange, connect_options, dumps_json, json_option, overwrite_option


def status_line(state: MonitorState) -> str:
    """One line a person reads at a glance (the live status on stderr)."""
    planned = f"/{state.photos_planned}" if state.photos_planned else ""
    item = (
        f"item {state.mission_seq}/{state.mission_total if state.mission_total is not None else '?'}"
        if state.mission_seq is not None
        else "item -"
    )
    link = f"link {state.link_quality_pct:.1f}%" if state.link_quality_pct is not None else "link -"
    beat = f"hb {state.heartbeat_age_s:.1f} s" if state.heartbeat_age_s is not None else "hb -"
    parts = [
        f"photos {state.photos_taken}{planned}",
        f"missed {len(state.missed_stations)}",
        item,
        link,
        beat,
        f"reconnects {state.reconnects}",
    ]
    if state.joined_late:
        parts.append(f"joined late ({state.photos_before_join} before)")
    if state.missing_streams:
        parts.append("NO " + ",".join(state.missing_streams))
    if not state.connected:
        parts.append("LINK LOST, reconnecting")
    elif state.flight_over:
        parts.append("landed")
    return " | ".join(parts)


class _StatusPrinter:
    """Rewrites one line on a terminal; elsewhere (a log, a pipe) prints a line now and then
    and whenever the link drops or comes back."""

    def __init__(self, every_s: float = 5.0) -> None:
        self.stream = sys.stderr  # at call time: whatever stderr is now (a test runner's too)
        self.tty = self.stream.isatty()
        self.every_s = every_s
        self.last_print = 0.0
        self.drops = 0
        self.reconnects = 0
        self.width = 0

    def __call__(self, state: MonitorState) -> None:
        if state.drops > self.drops:
            self.drops = state.drops
            self._line(f"link lost: {state.last_drop}; reconnecting, the recording goes on")
        if state.reconnects > self.reconnects:
            self.reconnects = state.reconnects
            self._line(f"reconnected ({state.reconnects} so far); the recording goes on")
        text = status_line(state)
        if self.tty:
            pad = max(self.width - len(text), 0)
            self.stream.write("\r" + text + " " * pad)
            self.stream.flush()
            self.width = len(text)
        elif time.monotonic() - self.last_print >= self.every_s:
            self.last_print = time.monotonic()
            click.echo(text, err=True)

    def _line(self, text: str) -> None:
        if self.tty and self.width:
            self.stream.write("\n")
            self.width = 0
        click.echo(text, err=True)

    def close(self) -> None:
        if self.tty and self.width:
            self.stream.write("\n")
            self.stream.flush()


@click.command(name="monitor")
@connect_options
@click.option(
    "--plan",
    "plan_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The plan folder (written by `sfap plan -o`) whose stations the photos are counted against.",
)
@click.option(
    "-o",
    "--output",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Recording folder: flight.tlog, triggers.csv, monitor.json.",
)
@overwrite_option
@click.option(
    "--reconnect-timeout-s",
    type=FiniteFloatRange(min=0.0),
    default=60.0,
    show_default=True,
    help="After a link drop, keep trying to reconnect for this many seconds.",
)
@click.option(
    "--keep-after-landing",
    is_flag=True,
    help="Keep recording after the vehicle lands and disarms (default: stop then).",
)
@json_option
def command(
    url: str,
    plan_dir: Path | None,
    out_dir: Path,
    overwrite: bool,
    reconnect_timeout_s: float,
    heartbeat_timeout_s: float,
    keep_after_landing: bool,
    signing_key_file: Path | None,
    require_signing: bool,
    as_json: bool,
) -> None:
    """Record every camera event and the whole MAVLink traffic of the link (every system, as a
    ground station logs it) to a .tlog and a trigger CSV, showing live on stderr: photos
    taken (from the vehicle's image index) / planned stations, stations missed so far, mission
    item, link quality (percent of messages received, from the MAVLink sequence numbers of
    every system on the link), age of the last heartbeat, reconnections. It asks the vehicle
    for position, attitude, clock and mission progress (ArduPilot sends none until asked) and
    warns, naming them, when they do not come; it follows the mission the vehicle holds (a
    re-fly uploaded in the field). A dropped link is reconnected and the recording goes on.
    Ends when the vehicle lands and disarms, or on Ctrl-C, with the files complete.

    Example: sfap monitor --connect tcp://127.0.0.1:5760 --plan out/gully -o flight/
    """
    # The recording folder, checked before connecting (a flight is not the time to find out).
    check_output_dir(out_dir, overwrite=overwrite)
    check_writable(out_dir, "recording folder")
    key = load_signing_key(signing_key_file)
    printer = _StatusPrinter()
    try:
        result = monitor(
            url,
            plan_dir,
            out_dir,
            on_update=printer,
            reconnect_timeout_s=reconnect_timeout_s,
            heartbeat_timeout_s=heartbeat_timeout_s,
            overwrite=overwrite,
            stop_when_landed=not keep_after_landing,
            signing_key=key,
            require_signing=require_signing,
        )
    finally:
        printer.close()
    _present(result, as_json)


def _present(result: MonitorResult, as_json: bool) -> None:
    state = result.state
    if as_json:
        click.echo(
            dumps_json(
                {
                    "reason": result.reason.value,
                    "tlog": str(result.tlog_path),
                    "trigger_csv": str(result.csv_path),
                    "summary": str(result.summary_path),
                    **state.as_dict(),
                }
            )
        )
        return
    why = {
        StopReason.LANDED: "the vehicle landed and disarmed",
        StopReason.STOPPED: "stopped",
        StopReason.INTERRUPTED: "interrupted (Ctrl-C)",
    }[result.reason]
    click.echo(f"recording closed ({why}); files complete:")
    click.echo(f"  telemetry log  {result.tlog_path}")
    click.echo(f"  trigger CSV    {result.csv_path}")
    click.echo(f"  summary        {result.summary_path}")
    planned = f" of {state.photos_planned} planned" if state.photos_planned else ""
    click.echo(f"photos: {state.photos_taken}{planned}; extra photos: {state.extra_photos}")
    if state.joined_late:
        click.echo(
            f"joined late: the vehicle had taken {state.photos_before_join} photos before the monitor "
            f"started; they are counted (from the vehicle's image index) but have no event in this "
            f"recording: geotag those frames from the vehicle's own log (DataFlash .bin or .ulg)"
        )
    if state.photos_unseen:
        click.echo(
            f"camera events lost on the link: {state.photos_unseen} (the image index skipped them; "
            f"the photos were taken, and stations they took may be listed as missed)"
        )
    if state.mission_changes:
        source = "the vehicle's mission" if state.stations_from == "vehicle" else "the plan"
        click.echo(
            f"the vehicle's mission changed {state.mission_changes} time(s); stations counted from {source}"
        )
    if state.missing_streams:
        click.echo(f"never received although asked for: {', '.join(state.missing_streams)}")
    if state.photos_planned:
        missed = state.missed_stations
        shown = ", ".join(str(i) for i in missed[:20]) + (" ..." if len(missed) > 20 else "")
        click.echo(f"stations missed: {len(missed)}" + (f" (station indices: {shown})" if missed else ""))
    quality = f"{state.link_quality_pct:.1f} %" if state.link_quality_pct is not None else "-"
    click.echo(
        f"link: {quality} of messages received since the last connection; "
        f"{state.drops} drops, {state.reconnects} reconnections"
    )
