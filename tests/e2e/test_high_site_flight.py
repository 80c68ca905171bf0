"""A survey at a site 400 m above sea level, flown end to end: plan -> mission.plan -> upload to
the simulated ArduPilot -> flight. The vehicle must fly at the planned height above the ground,
which proves that the survey's waypoints are relative to home: a waypoint written in
MAV_FRAME_GLOBAL (above sea level) with the height above ground as its altitude would be read
as 50 m above sea level, 350 m below the take-off point, and fly the survey into the ground.
Every example mission has home at 0 m, where the two frames coincide; this one does not.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from acquisition.clock import VirtualClock
from acquisition.link import Link
from acquisition.mavlink_items import is_global_frame, plain_frame
from acquisition.simulator.server import SimulatedVehicle
from acquisition.transfer import upload_mission
from planner.formats import read_mission
from planner.mission import MavCmd, MavFrame
from planner.plan_folder import write_outputs
from planner.spec import load_spec
from planner.survey import plan_survey

HOME_LAT, HOME_LON, HOME_AMSL_M = 42.2012, -1.4866, 400.0
HEIGHT_M = 50.0


def _write_spec(folder: Path) -> Path:
    # a 160 m x 100 m field beside home
    lat0, lon0 = HOME_LAT + 0.0003, HOME_LON + 0.0003
    dlat, dlon = 100 / 111_132.0, 160 / (111_320.0 * np.cos(np.radians(lat0)))
    ring = [[lon0, lat0], [lon0 + dlon, lat0], [lon0 + dlon, lat0 + dlat], [lon0, lat0 + dlat], [lon0, lat0]]
    area = {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}
    (folder / "field.geojson").write_text(json.dumps(area))
    spec = folder / "high.toml"
    spec.write_text(
        f"""name = "High field"
area = "field.geojson"

[camera]
model = "canon-eos-350d-20mm"

[survey]
altitude_agl_m = {HEIGHT_M}
front_overlap_pct = 70
side_overlap_pct = 60
speed_m_s = 8

[vehicle]
type = "multirotor"
home = [{HOME_LAT}, {HOME_LON}]
home_alt_amsl_m = {HOME_AMSL_M}
takeoff_alt_m = 30
autopilot = "ardupilot"
"""
    )
    return spec


def test_a_site_400_m_above_sea_level_is_flown_at_the_planned_height_above_ground(tmp_path: Path) -> None:
    plan = plan_survey(load_spec(_write_spec(tmp_path)))
    write_outputs(plan, tmp_path / "plan")
    mission = read_mission(tmp_path / "plan" / "mission.plan")
    assert mission.home.alt_amsl_m == HOME_AMSL_M
    # the frame of every positional item is pinned: relative to home, never above sea level
    positional = [it for it in mission.items if is_global_frame(it.frame)]
    assert positional
    assert {plain_frame(it.frame) for it in positional} == {MavFrame.GLOBAL_RELATIVE_ALT}
    assert all(it.alt_m <= HEIGHT_M + 1e-6 for it in positional)

    clock = VirtualClock()  # simulated time: the upload and the flight without their waits
    with SimulatedVehicle(
        home=mission.home, speedup=200, boot_delay_s=0.0, gps_fix_s=0.0, streams_on_request=False, clock=clock
    ) as vehicle:
        with Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0, clock=clock) as link:
            upload_mission(link, mission, timeout_s=0.5)
        vehicle.auto_start()
        assert vehicle.wait_landed(90), "the simulated flight did not end"
        shots = list(vehicle.flight.shots)
    assert len(shots) == len(plan.stations)
    survey_items = [it for it in mission.items if int(it.command) == MavCmd.NAV_WAYPOINT]
    assert survey_items
    # every photo at the planned height above the ground (the ground is flat at home's level)
    heights = np.array([shot.alt_rel_home_m for shot in shots])
    assert np.all(np.abs(heights - HEIGHT_M) < 0.05), heights
    # and what the vehicle reported: above sea level, home's elevation plus the height
    reported_amsl = np.array([shot.reported_alt_rel_home_m for shot in shots]) + HOME_AMSL_M
    assert np.all(np.abs(reported_amsl - (HOME_AMSL_M + HEIGHT_M)) < 3.0)
