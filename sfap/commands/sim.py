"""`sfap sim`: run a simulated vehicle (ArduPilot or PX4 flavour) on a MAVLink URL."""

from __future__ import annotations

from pathlib import Path

import click

from acquisition.simulator.server import (
    DEFAULT_HOME,
    SIMULATOR_BANNER,
    FaultConfig,
    SimulatedVehicle,
    serve,
)
from planner.mission import Autopilot, Mission, VehicleType

_PERCENT = click.FloatRange(0.0, 100.0)


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
    type=click.FloatRange(min=0.01, max=1000.0),
    default=1.0,
    show_default=True,
    help="Simulated seconds per wall-clock second.",
)
@click.option(
    "--loss-pct",
    type=_PERCENT,
    default=0.0,
    show_default=True,
    help="Messages lost, percent (each way).",
)
@click.option(
    "--duplicate-pct",
    type=_PERCENT,
    default=0.0,
    show_default=True,
    help="Messages delivered twice, percent (each way).",
)
@click.option(
    "--reorder-pct",
    type=_PERCENT,
    default=0.0,
    show_default=True,
    help="Messages swapped with the next one, percent (each way).",
)
@click.option(
    "--latency-s",
    type=click.FloatRange(0.0, 60.0),
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
    "--auto-start",
    is_flag=True,
    help="Arm and start the mission by itself once the GPS has a fix and a mission is stored "
    "(preloaded with --mission or uploaded later).",
)
@click.option(
    "--until-landed", is_flag=True, help="Stop once the vehicle has flown and landed (for scripts)."
)
@click.option(
    "--duration-s",
    type=click.FloatRange(min=0.0),
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
    auto_start: bool,
    until_landed: bool,
    duration_s: float | None,
) -> None:
    """Run a simulated vehicle that answers the MAVLink mission protocol as ArduPilot or PX4
    does, flies an uploaded mission when armed and set to AUTO, and emits telemetry and camera
    events. It is a simulator, not an aircraft, and says so.

    Example: sfap sim --listen tcpin://127.0.0.1:5760 --autopilot px4 --speedup 10
    """
    mission: Mission | None = None
    if mission_path is not None:
        from planner.formats import read_mission

        mission = read_mission(mission_path)
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
        home=mission.home if mission is not None else DEFAULT_HOME,
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
        if tlog_path is not None:
            click.echo(f"writing what it sends to {tlog_path}", err=True)
        if auto_start:
            vehicle.auto_start()
        try:
            why = serve(vehicle, duration_s=duration_s, until_landed=until_landed)
        except KeyboardInterrupt:
            why = "interrupted"
        shots = len(vehicle.flight.shots)
    click.echo(f"simulator stopped ({why}); {shots} photos taken", err=True)
