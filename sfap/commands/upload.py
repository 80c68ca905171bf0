"""``sfap upload``: send a .plan/.waypoints mission to an autopilot and prove it arrived whole.

Also home of the link options that ``upload``, ``download`` and ``clear`` share (defined once).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar

import click

from acquisition.errors import LinkError, join_sentences
from acquisition.link import Link
from acquisition.mission_protocol import DEFAULT_RETRIES, DEFAULT_TIMEOUT_S, TransferPhase
from acquisition.signing import load_signing_key
from acquisition.transfer import upload_mission
from acquisition.transfer_outcome import (
    MissionInputError,
    MissionInterruptedError,
    MissionState,
    MissionVerificationError,
    UploadResult,
)
from acquisition.vehicle_params import (
    DEFAULT_PARAM_RETRIES,
    DEFAULT_PARAM_TIMEOUT_S,
    ParamStatus,
    VehicleParameterError,
    check_parameters,
    required_parameters,
)
from planner.errors import MissionFileError, MissionValidationError
from planner.mission import validate_mission

from ..common import (
    FINITE_FLOAT,
    FiniteFloatRange,
    connect_options,
    echo_json,
    echo_table,
    json_option,
    progress,
)

F = TypeVar("F", bound=Callable[..., Any])

_PHASE_LABELS = {
    TransferPhase.UPLOAD: "uploading ",
    TransferPhase.VERIFY: "verifying ",
    TransferPhase.DOWNLOAD: "downloading",
    TransferPhase.CLEAR: "clearing  ",
}


def link_options(function: F) -> F:
    """The connection options (:func:`sfap.common.connect_options`) and the mission protocol's
    timeouts: the options of upload, download and clear."""
    options = [
        click.option(
            "--timeout-s",
            type=FiniteFloatRange(min=0.01),
            default=DEFAULT_TIMEOUT_S,
            show_default=True,
            help="Seconds to wait for the vehicle before repeating a mission message.",
        ),
        click.option(
            "--retries",
            type=click.IntRange(min=0),
            default=DEFAULT_RETRIES,
            show_default=True,
            help="How many times a mission message is repeated before giving up.",
        ),
    ]
    for option in reversed(options):
        function = option(function)
    return connect_options(function)


def open_link(
    url: str,
    signing_key_file: Path | None,
    require_signing: bool,
    heartbeat_timeout_s: float,
    *,
    nothing_sent_note: str = "",
) -> Link:
    """Open the link of the link options; ``nothing_sent_note`` is added to a failure."""
    try:
        key = load_signing_key(signing_key_file)
        return Link.open(
            url,
            heartbeat_timeout_s=heartbeat_timeout_s,
            signing_key=key,
            require_signing=require_signing,
        )
    except LinkError as error:
        if nothing_sent_note:
            # the same kind of error (a bad URL or key file stays bad usage), with the note
            raise type(error)(join_sentences(str(error), nothing_sent_note)) from error
        raise
    except KeyboardInterrupt as stop:
        if not nothing_sent_note:
            raise
        raise MissionInterruptedError(
            join_sentences(f"interrupted (Ctrl-C) while connecting to {url}", nothing_sent_note),
            mission_state=MissionState.UNCHANGED,
        ) from stop


class ProgressBars:
    """Turns the library's progress(phase, done, total) into one stderr bar per phase."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._stack = contextlib.ExitStack()
        self._phase: TransferPhase | None = None
        self._done = 0
        self._advance: Callable[[int], None] = lambda n: None

    def __call__(self, phase: TransferPhase, done: int, total: int) -> None:
        if phase is not self._phase:
            self._stack.close()
            self._stack = contextlib.ExitStack()
            self._advance = self._stack.enter_context(
                progress(_PHASE_LABELS.get(phase, str(phase)), total, self.enabled)
            )
            self._phase = phase
            self._done = 0
        if done > self._done:
            self._advance(done - self._done)
            self._done = done

    def close(self) -> None:
        self._stack.close()


@contextlib.contextmanager
def progress_bars(enabled: bool = True) -> Iterator[ProgressBars]:
    bars = ProgressBars(enabled)
    try:
        yield bars
    finally:
        bars.close()


@click.command("upload")
@click.argument("mission_file", type=click.Path(dir_okay=False, path_type=Path))
@link_options
@click.option(
    "--max-alt-rel-home-m",
    type=FINITE_FLOAT,
    default=None,
    help="The vehicle's altitude limit in metres above home; higher items are refused before "
    "anything is sent. Default: no limit.",
)
@click.option(
    "--max-home-distance-m",
    type=FiniteFloatRange(min=0.0),
    default=1000.0,
    show_default=True,
    help="Warn when the first waypoint is farther than this from the vehicle's home (metres): "
    "the vehicle is not where the survey is, or the mission is another site's.",
)
@click.option(
    "--allow-other-autopilot",
    is_flag=True,
    help="Send a mission planned for the other autopilot (ArduPilot/PX4) as it is (default: refuse).",
)
@click.option(
    "--set-params",
    is_flag=True,
    help="Set the vehicle parameters the mission needs to the value sfap names (RTL_AUTOLAND 2 "
    "for a plane's landing sequence) and read them back. Default: read them and name what to set.",
)
@json_option
def command(
    mission_file: Path,
    url: str,
    signing_key_file: Path | None,
    require_signing: bool,
    timeout_s: float,
    retries: int,
    heartbeat_timeout_s: float,
    max_alt_rel_home_m: float | None,
    max_home_distance_m: float,
    allow_other_autopilot: bool,
    set_params: bool,
    as_json: bool,
) -> None:
    """Upload MISSION_FILE (.plan or .waypoints) to a vehicle, read it back and verify it.

    Exits 0 only when every item read back matches what was sent (latitude and longitude to
    the degE7 unit, parameters to float32); otherwise it lists the items that differ, says what
    the vehicle now holds, and exits 1. A mission larger than the vehicle holds is refused at
    once with the excess (exit 1); a mission that fails validation, or was planned for the other
    autopilot, is not sent (exit 2). Warns when the first waypoint is far from the vehicle's home.

    Then it reads the vehicle parameters the mission needs (a plane's landing sequence needs
    RTL_AUTOLAND 1 or 2 on ArduPlane, a camera trigger CAM1_TYPE not 0) and names what to set
    (exit 1 while one is wrong); with --set-params it sets them and reads them back. Ctrl-C
    says what the vehicle then holds (exit 130).

    Example: sfap upload out/gully/mission.plan --connect serial:///dev/ttyUSB0:57600
    """
    nothing_sent = "Nothing was sent: the vehicle's mission is unchanged."
    from planner.formats import read_mission

    try:
        mission = read_mission(mission_file)
    except MissionFileError as error:
        raise MissionFileError(join_sentences(str(error), nothing_sent)) from error
    try:
        validate_mission(mission, max_alt_rel_home_m=max_alt_rel_home_m)
    except MissionValidationError as error:
        raise MissionInputError(f"{error}\n{nothing_sent}") from error
    with (
        open_link(
            url,
            signing_key_file,
            require_signing,
            heartbeat_timeout_s,
            nothing_sent_note=nothing_sent,
        ) as link,
        progress_bars() as bars,
    ):
        try:
            far = _far_from_home(link, mission, max_home_distance_m)
        except KeyboardInterrupt as stop:
            raise MissionInterruptedError(
                f"upload to {link.url} interrupted (Ctrl-C) before any item was sent",
                mission_state=MissionState.UNCHANGED,
            ) from stop
        try:
            result = upload_mission(
                link,
                mission,
                progress=bars,
                timeout_s=timeout_s,
                retries=retries,
                max_alt_rel_home_m=max_alt_rel_home_m,
                allow_other_autopilot=allow_other_autopilot,
            )
        except MissionVerificationError as error:
            bars.close()
            if as_json:
                echo_json(error.result.to_dict())
            raise
        requirements = required_parameters(
            mission.items, result.autopilot, result.vehicle_type or mission.vehicle_type
        )
        try:
            statuses = check_parameters(
                link,
                requirements,
                apply=set_params,
                timeout_s=min(timeout_s, DEFAULT_PARAM_TIMEOUT_S),
                retries=min(retries, DEFAULT_PARAM_RETRIES),
            )
        except KeyboardInterrupt as stop:
            raise MissionInterruptedError(
                "interrupted (Ctrl-C) while checking the vehicle's parameters",
                mission_state=MissionState.REPLACED_VERIFIED,
            ) from stop
    wrong = [status for status in statuses if status.value is not None and not status.ok]
    for status in statuses:
        if status.value is None:
            click.echo(f"warning: {status.describe()}", err=True)
    if as_json:
        echo_json(
            {
                **result.to_dict(),
                "first_waypoint_from_home_m": far,
                "parameters": [status.to_dict() for status in statuses],
            }
        )
    else:
        _present(mission_file, result, statuses)
    if wrong:
        raise VehicleParameterError(
            join_sentences(
                "the mission was uploaded and verified, but the vehicle will not fly it with its "
                "parameters as they are",
                *(status.describe() for status in wrong),
            )
        )


def _present(mission_file: Path, result: UploadResult, statuses: Sequence[ParamStatus]) -> None:
    rows = [
        ("file", str(mission_file)),
        ("vehicle", f"{result.autopilot.value} on {result.url}"),
        (
            "items",
            f"{result.items} (+ home)" if result.items_sent > result.items else str(result.items),
        ),
        ("upload", f"{result.upload_s:.1f} s ({result.items_resent} items sent again)"),
        ("read-back", f"{result.verify_s:.1f} s, every item matches"),
        ("state", result.state.value),
    ]
    rows += [("note", note) for note in result.notes]
    rows += [("parameter", status.describe()) for status in statuses]
    echo_table(rows, title="Mission uploaded and verified")


def _far_from_home(link: Link, mission: Any, limit_m: float) -> float | None:
    """The first waypoint's distance from the vehicle's home (m), with a warning on stderr when
    it is more than ``limit_m``; None when the vehicle has no home yet."""
    from acquisition.transfer import first_waypoint_distance_m, request_home_position

    home = request_home_position(link, timeout_s=1.0, retries=1)
    if home is None:
        click.echo(
            "note: the vehicle reports no home position yet (no GPS fix?): the distance to the first "
            "waypoint is not checked",
            err=True,
        )
        return None
    distance = first_waypoint_distance_m(mission.items, home)
    if distance is not None and distance > limit_m:
        click.echo(
            f"warning: the first waypoint is {distance / 1000:.1f} km from the vehicle's home "
            f"({home.lat_deg:.6f}, {home.lon_deg:.6f}); more than --max-home-distance-m {limit_m:g} m. "
            f"Check that the vehicle is at the survey site and the mission is this site's: it would "
            f"fly {distance / 1000:.1f} km to start.",
            err=True,
        )
    return distance
