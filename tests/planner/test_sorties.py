"""Sorties by endurance: every sortie within endurance less its reserve, and the sorties together
fly the whole plan's stations once each."""

from __future__ import annotations

from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sortie_cases import GEOD_WGS84 as GEOD
from sortie_cases import LAT0, LON0, M_PER_DEG_LAT, M_PER_DEG_LON, lonlat_polygon, spec_with, station_keys

from planner.errors import PlanningError
from planner.mission import MavCmd
from planner.plan import SurveyPlan
from planner.sorties import split_sorties
from planner.survey import plan_polygons


def path_length_m(plan: SurveyPlan) -> float:
    """Home, every positional item of the mission, home: on the ellipsoid (pyproj), not the
    planner's projected path."""
    lons = [plan.home.lon_deg]
    lats = [plan.home.lat_deg]
    for item in plan.mission.items:
        if int(item.command) == MavCmd.NAV_WAYPOINT:
            lons.append(item.lon_deg)
            lats.append(item.lat_deg)
    lons.append(plan.home.lon_deg)
    lats.append(plan.home.lat_deg)
    return float(GEOD.line_length(lons, lats))


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    width=st.floats(200.0, 700.0),
    height=st.floats(200.0, 600.0),
    endurance=st.floats(300.0, 1500.0),
    reserve=st.floats(0.0, 40.0),
    crosshatch=st.booleans(),
    home=st.sampled_from([(0.0, 0.0), (-150.0, -80.0), (300.0, 700.0)]),
)
def test_every_sortie_fits_and_the_sorties_fly_the_whole_plan_once(
    width: float, height: float, endurance: float, reserve: float, crosshatch: bool, home: tuple[float, float]
) -> None:
    home_lat = LAT0 + home[1] / M_PER_DEG_LAT
    home_lon = LON0 + home[0] / M_PER_DEG_LON
    spec = spec_with(
        {"crosshatch": crosshatch, "transit_speed_m_s": 12.0},
        {"endurance_s": endurance, "reserve_pct": reserve, "home": [home_lat, home_lon]},
    )
    area = lonlat_polygon([(0, 0), (width, 0), (width, height), (0.3 * width, height)])
    plan = plan_polygons(spec, [area], [])
    usable = endurance * (1 - reserve / 100.0)
    try:
        sorties = split_sorties(plan)
    except PlanningError as error:
        # Only when one line alone, from home and back, is longer than the battery allows.
        assert "sortie of its own" in str(error)
        return
    whole = station_keys(plan)
    together: Counter[tuple[int, float, float]] = Counter()
    for sortie in sorties:
        s = sortie.plan
        assert s.summary.flight_time_s <= usable + 1e-6
        # An independent lower bound of the time: the ellipsoidal length of the items at the
        # transit speed, the climbs and the descent at the climb rate.
        climbs_s = (2 * s.summary.altitude_agl_m) / spec.vehicle.climb_rate_m_s
        assert path_length_m(s) / 12.0 + climbs_s <= s.summary.flight_time_s * 1.01
        items = s.mission.items
        assert int(items[0].command) == MavCmd.NAV_TAKEOFF
        assert (items[0].lat_deg, items[0].lon_deg) == pytest.approx((home_lat, home_lon))
        assert int(items[-1].command) == MavCmd.NAV_RETURN_TO_LAUNCH
        assert s.summary.photo_count == len(s.stations)
        together.update(station_keys(s))
    assert together == whole  # every station once, none twice, none left out
    assert max(together.values()) == 1
    if plan.summary.flight_time_s > usable:
        assert len(sorties) >= 2


def test_endurance_shorter_than_a_line_names_the_line_time_and_the_fix() -> None:
    spec = spec_with({}, {"endurance_s": 120, "reserve_pct": 20})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (1500, 0), (1500, 300), (0, 300)])], [])
    with pytest.raises(PlanningError) as info:
        split_sorties(plan)
    text = str(info.value)
    assert "min as a sortie of its own" in text and "1.6 min one battery allows" in text
    assert "raise endurance_s" in text


def test_battery_capacity_and_consumption_give_the_endurance() -> None:
    spec = spec_with({}, {"battery_capacity_mah": 5000, "consumption_ma": 10000, "reserve_s": 600})
    assert spec.vehicle.endurance_s == pytest.approx(1800.0)
    assert spec.vehicle.usable_flight_s == pytest.approx(1200.0)  # 600 s > 20 % of 1800 s


def test_scales_as_sorties_never_mix_heights() -> None:
    spec = spec_with(
        {"scale": [{"altitude_agl_m": 120.0}], "scale_flight": "sorties"},
        {"endurance_s": 600, "reserve_pct": 20},
    )
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (500, 0), (500, 400), (0, 400)])], [])
    sorties = split_sorties(plan)
    for sortie in sorties:
        heights = {round(float(a), 3) for a in sortie.plan.stations.alt_agl_m}
        assert len(heights) == 1
    assert station_keys(plan) == sum((station_keys(s.plan) for s in sorties), Counter())


def test_a_planes_sorties_take_off_turn_and_land_as_a_plane() -> None:
    """Each sortie of a fixed-wing plan is flown by the plane the spec describes, like the whole
    plan: NAV_TAKEOFF at the spec's take-off pitch, and the landing sequence (DO_LAND_START after
    the survey, NAV_LAND last)."""
    import dataclasses
    from pathlib import Path

    from planner.spec import load_spec
    from planner.survey import plan_survey

    spec = load_spec(Path(__file__).parents[2] / "missions" / "huesca-plane-block.toml")
    whole = plan_survey(spec)
    minutes = whole.summary.flight_time_s / 60.0
    vehicle = dataclasses.replace(
        spec.vehicle, endurance_s=whole.summary.flight_time_s * 0.6, reserve_pct=0.0
    )
    sorties = split_sorties(plan_survey(dataclasses.replace(spec, vehicle=vehicle)))
    assert len(sorties) >= 2, f"{minutes:.1f} min of flight in 0.6 of its time must take two sorties"

    def commands(plan: SurveyPlan) -> list[int]:
        return [int(item.command) for item in plan.mission.items]

    for plan in [whole, *(s.plan for s in sorties)]:
        cmds = commands(plan)
        takeoffs = [item for item in plan.mission.items if item.command == MavCmd.NAV_TAKEOFF]
        assert len(takeoffs) == 1 and takeoffs[0].param1 == pytest.approx(spec.vehicle.takeoff_pitch_deg)
        assert MavCmd.DO_LAND_START in cmds and cmds[-1] == MavCmd.NAV_LAND
        assert cmds.index(MavCmd.DO_LAND_START) > max(
            i for i, c in enumerate(cmds) if c == MavCmd.DO_SET_CAM_TRIGG_DIST
        )
