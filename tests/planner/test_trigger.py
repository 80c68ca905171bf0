"""How an autopilot fires a distance-triggered camera (planner.trigger): each autopilot's distance
against pyproj's geodesic on that autopilot's own sphere, and the run margins that keep the last
photo firing."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod

from planner import trigger as trig
from planner.lines import Segment
from planner.mission import Autopilot

PX4_SPHERE = Geod(a=6_371_000.0, b=6_371_000.0)
WGS84 = Geod(ellps="WGS84")
#: A start anywhere a survey flies, a bearing, and a baseline of a trigger distance or a line.
BASELINES = {
    "lat": st.floats(-70.0, 70.0), "lon": st.floats(-179.0, 179.0), "bearing": st.floats(0.0, 360.0),
    "distance_m": st.floats(1.0, 2000.0),
}  # fmt: skip


@settings(max_examples=80, deadline=None)
@given(**BASELINES)
def test_px4_measures_on_its_sphere(lat: float, lon: float, bearing: float, distance_m: float) -> None:
    lon1, lat1, _ = PX4_SPHERE.fwd(lon, lat, bearing, distance_m)
    measured = float(trig.autopilot_distance_m(lat, lon, lat1, lon1, Autopilot.PX4))
    assert measured == pytest.approx(distance_m, rel=1e-6, abs=1e-6)


@settings(max_examples=80, deadline=None)
@given(**BASELINES)
def test_ardupilot_measures_on_its_sphere_between_positions_in_1e7_degrees(
    lat: float, lon: float, bearing: float, distance_m: float
) -> None:
    """Location::get_distance: positions held as integers of 1e-7 degree, on a sphere of
    6,378,100 m (LOCATION_SCALING_FACTOR); over a trigger distance its flat approximation
    matches the sphere's geodesic (pyproj) to well under a millimetre."""
    ardupilot_sphere = Geod(a=6_378_100.0, b=6_378_100.0)
    lon1, lat1, _ = WGS84.fwd(lon, lat, bearing, distance_m)
    held = [round(v * 1e7) / 1e7 for v in (lon, lat, lon1, lat1)]
    _, _, expected = ardupilot_sphere.inv(*held)
    measured = float(trig.autopilot_distance_m(lat, lon, lat1, lon1, Autopilot.ARDUPILOT))
    assert measured == pytest.approx(expected, rel=2e-6, abs=5e-4)
    exact = float(
        trig.autopilot_distance_m(lat, lon, lat1, lon1, Autopilot.ARDUPILOT, integer_positions=False)
    )
    assert exact == pytest.approx(ardupilot_sphere.inv(lon, lat, lon1, lat1)[2], rel=2e-6, abs=5e-4)


@settings(max_examples=200, deadline=None)
@given(spacing_m=st.floats(0.5, 200.0), speed_m_s=st.floats(0.5, 30.0))
def test_a_run_is_as_long_as_the_drift_allows_and_no_longer(spacing_m: float, speed_m_s: float) -> None:
    """The first photo up to one loop step late, each later one +- half a step: the worst
    drift of n stations, step + (n - 1) step / 2, stays within DRIFT_SHARE of half the spacing;
    one station more would not (the module docstring's rule, written out here)."""
    step = speed_m_s / 50.0  # ArduPilot checks at 50 Hz
    n = trig.max_run_stations(spacing_m, speed_m_s)
    room = trig.DRIFT_SHARE * spacing_m / 2
    assert n >= 1
    if step <= room:
        assert step + (n - 1) * step / 2 <= room + 1e-9
        assert step + n * step / 2 > room - 1e-9
    else:
        assert n == 1
    assert trig.station_step_m(spacing_m, speed_m_s) == pytest.approx(spacing_m - step / 2)


@settings(max_examples=100, deadline=None)
@given(count=st.integers(1, 3000), spacing_m=st.floats(2.0, 80.0), speed_m_s=st.floats(1.0, 25.0))
def test_split_runs_keep_every_station_and_join_straight_on(
    count: int, spacing_m: float, speed_m_s: float
) -> None:
    seg = Segment(row=0, v_m=12.0, u_first_m=-40.0, spacing_m=spacing_m, count=count)
    runs = trig.split_for_trigger([seg], speed_m_s)
    limit = trig.max_run_stations(spacing_m, speed_m_s)
    assert all(1 <= r.count <= limit for r in runs)
    stations = np.concatenate([r.u_first_m + np.arange(r.count) * r.spacing_m for r in runs])
    assert np.allclose(stations, seg.u_first_m + np.arange(count) * spacing_m)
    assert len(runs) == math.ceil(count / limit)
    # Runs follow each other without a turn: joined inside, free at the two ends.
    assert not runs[0].join_lo and not runs[-1].join_hi
    assert all(a.join_hi and b.join_lo for a, b in itertools.pairwise(runs))
