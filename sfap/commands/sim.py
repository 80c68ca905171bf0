"""`sfap sim`: run a simulated vehicle (ArduPilot or PX4 flavour) on a MAVLink URL."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from acquisition.simulator.camera import FrameCard
from acquisition.simulator.faults import FaultConfig
from acquisition.simulator.server import (
    DEFAULT_HOME,
    SIMULATOR_BANNER,
    SimulatedVehicle,
    serve,
)
from planner.errors import InputError
from planner.mission import Autopilot, HomePosition, Mission, VehicleType
from planner.outputs import check_writable

from ..common import FiniteFloatRange

F = TypeVar("F", bound=Callable[..., Any])


def _percent_option(name: str, help_text: str) -> Callable[[F], F]:
    """A fault rate option: 0-100 %, default 0."""
    percent = FiniteFloatRange(0.0, 100.0)
    return click.option(name, type=percent, default=0.0, show_default=True, help=help_text)


@click.command(name="sim")
@click.option(
    "--listen",
    default="tcpin://127.0.0.1:5760",
    show_default=True,
    help="Where the vehicle listens: tcpin://HOST:PORT or udpin://HOST:PORT (port 0: any free "
    "port), or udpout://HOST:PORT to send to a ground station.",
)
@click.option(
    "--autopilot",
    type=click.Choice([a.value for a in Autopilot]),
    default=Autopilot.ARDUPILOT.value,
    show_default=True,
    help="Which autopilot's mission protocol to speak (ArduPilot: home at item 0).",
)
@click.option(
    "--vehicle",
    "vehicle_type",
    type=click.Choice([VehicleType.MULTIROTOR.value, VehicleType.FIXED_WING.value]),
    default=VehicleType.MULTIROTOR.value,
    show_default=True,
    help="Airframe: multirotor (quadrotor) or fixed_wing.",
)
@click.option(
    "--speedup",
    type=FiniteFloatRange(min=0.01, max=1000.0),
    default=1.0,
    show_default=True,
    help="Simulated seconds per wall-clock second.",
)
@_percent_option("--loss-pct", "Messages lost, percent (each way).")
@_percent_option("--duplicate-pct", "Messages delivered twice, percent (each way).")
@_percent_option("--reorder-pct", "Messages swapped with the next one, percent (each way).")
@click.option(
    "--latency-s",
    type=FiniteFloatRange(0.0, 60.0),
    default=0.0,
    show_default=True,
    help="Delay added to every message, wall seconds (each way).",
)
@click.option(
    "--refuse",
    type=click.Choice(["no_space", "invalid"]),
    default=None,
    help="Refuse every upload: no_space (MAV_MISSION_NO_SPACE) or invalid "
    "(MAV_MISSION_INVALID at the middle item).",
)
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Seed of the fault and GPS-noise random numbers.",
)
@click.option(
    "--tlog",
    "tlog_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write everything the vehicle sends to this .tlog file.",
)
@click.option(
    "--mission",
    "mission_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Preload this mission (.plan or .waypoints); its home becomes the vehicle's home.",
)
@click.option(
    "--home",
    "home_text",
    default=None,
    metavar="LAT_DEG,LON_DEG,ALT_AMSL_M",
    help="Where the vehicle stands: latitude and longitude (degrees, WGS84) and the ground's "
    "elevation (m above mean sea level). Default: the home of --plan or --mission, else the home "
    "of the first mission uploaded (the vehicle moves there before its first flight).",
)
@click.option(
    "--plan",
    "plan_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="A plan folder (`sfap plan -o DIR`): the vehicle stands at its home (mission.plan's "
    "planned home, elevation included).",
)
@click.option(
    "--frames",
    "frames_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Write the camera's frames here: a small JPEG per photo with its capture time "
    "(EXIF DateTimeOriginal) on the camera's clock. The folder must hold no frames yet.",
)
@click.option(
    "--camera-offset-s",
    type=FiniteFloatRange(-86400.0, 86400.0),
    default=0.0,
    show_default=True,
    help="How far the camera's clock is ahead of UTC (seconds; negative: behind); with --frames.",
)
@click.option(
    "--drop-frame",
    "drop_frames",
    type=click.IntRange(min=1),
    multiple=True,
    help="Photo number (1 = first) whose frame the camera does not write; repeatable.",
)
@click.option(
    "--extra-frame",
    "extra_frames",
    type=click.IntRange(min=1),
    multiple=True,
    help="Photo number after which the camera writes one frame more, 0.4 s later, with no "
    "camera event (a double fire); repeatable.",
)
@click.option(
    "--streams",
    type=click.Choice(["on-request", "always"]),
    default=None,
    help="Periodic telemetry: on-request (ArduPilot's default on a serial port: nothing but "
    "heartbeats until a ground station asks) or always (PX4). Default: as the autopilot does.",
)
@click.option(
    "--auto-start",
    is_flag=True,
    help="Arm and start the mission by itself once the GPS has a fix and a mission is stored "
    "(preloaded with --mission or uploaded later) and, when telemetry is on request, once a "
    "ground station (sfap monitor) has asked for it.",
)
@click.option(
    "--until-landed",
    is_flag=True,
    help="Stop once the vehicle has flown, landed and disarmed (for scripts); 15 s later when a "
    "ground station is watching (asked for telemetry).",
)
@click.option(
    "--duration-s",
    type=FiniteFloatRange(min=0.0),
    default=None,
    help="Stop after this many wall seconds (default: run until Ctrl-C).",
)
def command(
    listen: str,
    autopilot: str,
    vehicle_type: str,
    speedup: float,
    loss_pct: float,
    duplicate_pct: float,
    reorder_pct: float,
    latency_s: float,
    refuse: str | None,
    seed: int,
    tlog_path: Path | None,
    mission_path: Path | None,
    home_text: str | None,
    plan_dir: Path | None,
    frames_dir: Path | None,
    camera_offset_s: float,
    drop_frames: tuple[int, ...],
    extra_frames: tuple[int, ...],
    streams: str | None,
    auto_start: bool,
    until_landed: bool,
    duration_s: float | None,
) -> None:
    """Run a simulated vehicle that answers the MAVLink mission protocol as ArduPilot or PX4
    does, flies an uploaded mission when armed and set to AUTO, and emits telemetry and camera
    events. It is a simulator, not an aircraft, and says so.

    Example: sfap sim --listen tcpin://127.0.0.1:5760 --plan out/gully --frames out/frames
    --speedup 20 --auto-start
    """
    from planner.formats import read_mission

    # What the simulator will write, checked before it starts (it writes as it flies).
    if frames_dir is not None:
        check_writable(frames_dir, "frames folder")
    if tlog_path is not None:
        check_writable(tlog_path, "tlog")
    mission: Mission | None = None
    if mission_path is not None:
        mission = read_mission(mission_path)
    home = None
    if home_text is not None:
        home = _parse_home(home_text)
    elif plan_dir is not None:
        plan_file = plan_dir / "mission.plan"
        if not plan_file.is_file():
            raise click.BadParameter(
                f"{plan_file} does not exist; give the folder written by `sfap plan -o`", param_hint="--plan"
            )
        home = read_mission(plan_file).home
    elif mission is not None:
        home = mission.home
    card = None
    if frames_dir is not None:
        card = FrameCard(frames_dir, clock_offset_s=camera_offset_s, drop=drop_frames, extra=extra_frames)
    elif drop_frames or extra_frames or camera_offset_s:
        raise click.BadParameter(
            "needs --frames (where the frames are written)", param_hint="--camera-offset-s"
        )
    faults = FaultConfig(
        loss_pct=loss_pct,
        duplicate_pct=duplicate_pct,
        reorder_pct=reorder_pct,
        latency_s=latency_s,
        refuse=refuse,
        seed=seed,
    )
    vehicle = SimulatedVehicle(
        url=listen,
        autopilot=Autopilot(autopilot),
        faults=faults,
        speedup=speedup,
        vehicle_type=VehicleType(vehicle_type),
        tlog_path=tlog_path,
        home=home if home is not None else DEFAULT_HOME,
        streams_on_request=None if streams is None else streams == "on-request",
        follow_mission_home=home is None,
        frames=card,
    )
    if mission is not None:
        vehicle.load_mission(mission.items)
    with vehicle:
        click.echo(
            f"{SIMULATOR_BANNER}: {autopilot} {vehicle_type}, a simulator and not an aircraft",
            err=True,
        )
        click.echo(f"connect a ground station to {vehicle.url_for_client}", err=True)
        if mission is not None:
            click.echo(f"mission preloaded: {len(mission.items)} items from {mission_path}", err=True)
        where = vehicle.home
        click.echo(
            f"home {where.lat_deg:.7f}, {where.lon_deg:.7f}, ground at {where.alt_amsl_m:g} m AMSL"
            + ("" if home is not None else " (moves to the first uploaded mission's home)"),
            err=True,
        )
        if tlog_path is not None:
            click.echo(f"writing what it sends to {tlog_path}", err=True)
        if card is not None:
            click.echo(
                f"camera frames to {card.folder} (camera clock {card.clock_offset_s:+g} s from UTC)", err=True
            )
        if auto_start:
            vehicle.auto_start(wait_for_telemetry=vehicle.streams_on_request)
        try:
            why = serve(vehicle, duration_s=duration_s, until_landed=until_landed, linger_s=15.0)
        except KeyboardInterrupt:
            why = "interrupted"
        shots = len(vehicle.flight.shots)
    frames = f", {card.frames} frames in {card.folder}" if card is not None else ""
    click.echo(f"simulator stopped ({why}); {shots} photos taken{frames}", err=True)


def _parse_home(text: str) -> HomePosition:
    parts = [p.strip() for p in text.split(",")]
    try:
        if len(parts) != 3:
            raise ValueError
        lat, lon, alt = (float(p) for p in parts)
        if not (-90 <= lat <= 90 and -180 <= lon <= 180 and -500 <= alt <= 9000):
            raise InputError("latitude -90..90, longitude -180..180, elevation -500..9000 m")
        return HomePosition(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
    except (ValueError, InputError) as error:
        raise click.BadParameter(
            f"{text!r} is not LAT,LON,ALT (degrees, degrees, metres above mean sea level), "
            f"for example 42.2012,-1.4866,320" + (f": {error}" if str(error) else ""),
            param_hint="--home",
        ) from error
