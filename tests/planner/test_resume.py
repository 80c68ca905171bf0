"""Resume plans: a resume plan flies exactly the stations left, from the station given or the
last one the monitor's record reached."""

from __future__ import annotations

import csv
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sortie_cases import M_PER_DEG_LAT, M_PER_DEG_LON, lonlat_polygon, spec_with, station_keys

from planner.errors import InputError
from planner.mission import MavCmd
from planner.resume import last_station_from_record, resume_plan
from planner.survey import plan_polygons


@settings(max_examples=10, deadline=None, derandomize=True)
@given(share=st.floats(0.0, 0.999))
def test_resume_flies_exactly_the_stations_left(share: float) -> None:
    spec = spec_with({"crosshatch": True}, {})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (400, 0), (400, 300), (0, 300)])], [])
    n = int(share * len(plan.stations))
    resumed = resume_plan(plan, n)
    st_ = plan.stations
    left = Counter(
        (int(p), round(float(x), 1), round(float(y), 1))
        for p, x, y in zip(st_.pass_index[n:], st_.x_m[n:], st_.y_m[n:], strict=True)
    )
    assert station_keys(resumed) == left
    assert int(resumed.mission.items[0].command) == MavCmd.NAV_TAKEOFF


def test_resume_from_the_monitor_record(tmp_path: Path) -> None:
    spec = spec_with({}, {})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (400, 0), (400, 300), (0, 300)])], [])
    reached = len(plan.stations) // 3
    rng = np.random.default_rng(1)
    with (tmp_path / "triggers.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time_utc_s", "seq", "lat_deg", "lon_deg", "alt_amsl_m", "alt_rel_home_m",
                         "roll_deg", "pitch_deg", "yaw_deg", "source"])  # fmt: skip
        for k in range(reached + 1):
            # GNSS noise of about a metre, as a plain receiver records
            lon = plan.stations.lon_deg[k] + rng.normal(0, 1.0) / M_PER_DEG_LON
            lat = plan.stations.lat_deg[k] + rng.normal(0, 1.0) / M_PER_DEG_LAT
            writer.writerow([1000 + k, k, lat, lon, 100, 60, 0, 0, 0, "CAMERA_FEEDBACK"])
    assert last_station_from_record(plan, tmp_path) == reached
    (tmp_path / "other").mkdir()
    with pytest.raises(InputError, match=r"no triggers\.csv"):
        last_station_from_record(plan, tmp_path / "other")


def test_resume_from_a_station_outside_the_plan_is_refused() -> None:
    spec = spec_with({}, {})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])], [])
    with pytest.raises(InputError, match="has stations 0 to"):
        resume_plan(plan, len(plan.stations))
