"""Fly a planned mission in the simulator and measure each photo's distance from its line.

The line of a photo is read from the mission items themselves, not from the planner's path: a
photo taken while the vehicle flies toward the waypoint of item ``k`` (its MISSION_CURRENT, or
the DO command that started the camera there) belongs to the leg from the NAV waypoint before
``k`` to the NAV waypoint at or after it; the distance is the perpendicular distance to that
leg's line.

    python -m tests.support.plane_flight missions/huesca-plane-block.toml
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquisition.mission_stations import mission_station_plan
from acquisition.simulator.flight import FlightConfig, FlightSimulator
from acquisition.simulator.mission_execution import is_nav
from acquisition.station_tracker import StationTracker
from acquisition.transfer import home_item
from planner.mission import Mission, MissionItem
from planner.spec import load_spec
from planner.survey import SurveyPlan, plan_survey


@dataclass(frozen=True)
class LineFit:
    """Distances (m) of the photos from their lines, and the counts."""

    distances_m: np.ndarray
    photos: int
    planned: int
    feedback: int
    taken: int
    missed: int
    extra: int

    def summary(self) -> str:
        d = self.distances_m
        return (
            f"photos {self.photos} (planned {self.planned}, CAMERA_FEEDBACK {self.feedback}; the "
            f"monitor's tally: taken {self.taken}, missed {self.missed}, extra {self.extra}); "
            f"distance from the line: median {np.median(d):.2f} m, p95 {np.percentile(d, 95):.2f} m, "
            f"max {d.max():.2f} m"
        )


def fly_mission(
    mission: Mission, *, seed: int = 0, limit_s: float = 20_000.0, feedback: list[object] | None = None
) -> FlightSimulator:
    """Upload (home item first, as ArduPilot stores it), arm, AUTO, and fly until landed; the
    CAMERA_FEEDBACK messages go to ``feedback``."""
    sim = FlightSimulator(
        autopilot=mission.autopilot,
        vehicle_type=mission.vehicle_type,
        home=mission.home,
        config=FlightConfig(seed=seed),
    )
    items = [home_item(mission.home), *mission.items] if sim.first_index == 1 else list(mission.items)
    sim.set_mission(items)
    sim.step(2.0)
    assert sim.arm() == (True, "") and sim.set_mode(
        1, 10 if mission.vehicle_type.value == "fixed_wing" else 3
    )
    while not sim.has_landed_after_flight and sim.time_s < limit_s:
        msgs = sim.step(5.0)
        if feedback is not None:
            feedback.extend(m for m in msgs if m.get_type() == "CAMERA_FEEDBACK")  # type: ignore[attr-defined]
    return sim


def photo_line_distances_m(sim: FlightSimulator) -> np.ndarray:
    items: list[MissionItem] = sim.mission.items
    out = []
    for shot in sim.shots:
        k = shot.mission_seq
        nxt = next(i for i in range(k, len(items)) if is_nav(items[i].command))
        prev = next(i for i in range(k - 1 if nxt == k else k, -1, -1) if is_nav(items[i].command))
        a = sim.frame.to_xy(items[prev].lon_deg, items[prev].lat_deg)
        b = sim.frame.to_xy(items[nxt].lon_deg, items[nxt].lat_deg)
        ax, ay, bx, by = float(a[0]), float(a[1]), float(b[0]), float(b[1])
        n = math.hypot(bx - ax, by - ay)
        out.append(abs((shot.x_m - ax) * (by - ay) - (shot.y_m - ay) * (bx - ax)) / n)
    return np.asarray(out, float)


def line_fit(plan: SurveyPlan, *, seed: int = 0) -> LineFit:
    """Fly ``plan`` and measure it; the monitor's station tracker (acquisition.station_tracker,
    stations replayed from the mission as the monitor does) tallies the camera events at their
    reported positions."""
    feedback: list[object] = []
    sim = fly_mission(plan.mission, seed=seed, feedback=feedback)
    assert sim.has_landed_after_flight, "the simulated flight did not land"
    stations = mission_station_plan(list(plan.mission.items))
    assert stations is not None
    tracker = StationTracker(stations)
    extra = 0
    for n, msg in enumerate(feedback):
        if tracker.add_event(n, msg.lat / 1e7, msg.lng / 1e7) is None:  # type: ignore[attr-defined]
            extra += 1
    tracker.end_flight()
    return LineFit(
        distances_m=photo_line_distances_m(sim),
        photos=len(sim.shots),
        planned=len(plan.stations),
        feedback=len(feedback),
        taken=tracker.taken_count,
        missed=len(tracker.missed()),
        extra=extra,
    )


def main(argv: list[str]) -> int:
    for name in argv:
        fit = line_fit(plan_survey(load_spec(Path(name))))
        print(f"{name}: {fit.summary()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
