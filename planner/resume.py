"""Resume plans for a flight cut short.

A resume plan flies what is left of a plan from one station on (the station's index in flight
order, the ``station`` property of stations.geojson): the line of that station from that station,
then every line the plan flies after it. The station can be given, or read from the monitor's
triggers.csv: the last planned station a camera event was recorded at.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np

from .errors import InputError, PlanningError
from .lines import Segment
from .partial import build_part, part_plan, plan_layout, segment_xy, station_keys
from .plan import SurveyPlan

#: The largest distance between a recorded camera event and the planned station it is matched
#: to, as a share of the station's trigger distance (and at least MIN_MATCH_M).
MATCH_SHARE = 0.5
MIN_MATCH_M = 5.0


def resume_plan(plan: SurveyPlan, from_station: int) -> SurveyPlan:
    """What is left of ``plan`` from station ``from_station`` on (0-based flight order, the
    ``station`` of stations.geojson): that station and every later one, as one mission from home."""
    layout = plan_layout(plan)
    n = len(plan.stations)
    if not 0 <= from_station < n:
        raise InputError(
            f"--resume-from {from_station}: the plan has stations 0 to {n - 1} (the station property "
            f"of stations.geojson); give one of them"
        )
    st = plan.stations
    remaining = set(station_keys(st.pass_index[from_station:], st.x_m[from_station:], st.y_m[from_station:]))
    pass_plans = []
    for pp in layout.pass_plans:
        parts: list[tuple[Segment, int, int]] = []  # (segment, first kept k, last kept k)
        for seg in pp.segments:
            x, y = segment_xy(pp, seg)
            kept = [
                k
                for k in range(seg.count)
                if (pp.index, round(float(x[k]), 2), round(float(y[k]), 2)) in remaining
            ]
            if kept:
                parts.append((seg, kept[0], kept[-1]))
        new_segments = []
        for i, (seg, k0, k1) in enumerate(parts):
            whole_before = i > 0 and parts[i - 1][2] == parts[i - 1][0].count - 1
            whole_after = i + 1 < len(parts) and parts[i + 1][1] == 0
            new_segments.append(
                dataclasses.replace(
                    seg,
                    u_first_m=seg.u_first_m + k0 * seg.spacing_m,
                    count=k1 - k0 + 1,
                    join_lo=seg.join_lo and k0 == 0 and whole_before and parts[i - 1][0].row == seg.row,
                    join_hi=(
                        seg.join_hi and k1 == seg.count - 1 and whole_after and parts[i + 1][0].row == seg.row
                    ),
                )
            )
        pass_plans.append(dataclasses.replace(pp, segments=tuple(new_segments)))
    built = build_part(plan, layout, pass_plans)
    resumed = part_plan(plan, layout, built, f"{plan.name} resumed from station {from_station}", pass_plans)
    if len(resumed.stations) != n - from_station:
        raise PlanningError(
            f"the resume plan holds {len(resumed.stations)} stations, not the {n - from_station} left "
            f"after station {from_station}; a planner bug: report it with the mission spec"
        )
    return resumed


def last_station_from_record(plan: SurveyPlan, record: Path) -> int:
    """The last planned station a camera event of the monitor's record (its folder, or its
    triggers.csv) was taken at, in flight order: each event is matched to the next planned
    station within MATCH_SHARE of the trigger distance (at least MIN_MATCH_M)."""
    path = record / "triggers.csv" if record.is_dir() else record
    if not path.is_file():
        raise InputError(f"{record}: no triggers.csv there; give the folder sfap monitor recorded into")
    try:
        with path.open(encoding="utf-8", newline="") as handle:
            rows = list(csv.DictReader(handle))
        points = [(float(r["lon_deg"]), float(r["lat_deg"])) for r in rows]
    except (KeyError, ValueError, TypeError, UnicodeDecodeError, csv.Error) as error:
        raise InputError(f"{path}: not a triggers.csv of sfap monitor ({error})") from None
    points = [p for p in points if math.isfinite(p[0]) and math.isfinite(p[1])]
    if not points:
        raise InputError(f"{path}: no camera event with a position; give the station with --resume-from")
    st = plan.stations
    trigger_m = {p.index: p.trigger_distance_m for p in plan.passes}
    radius = np.array([max(MIN_MATCH_M, MATCH_SHARE * trigger_m[int(p)]) for p in st.pass_index])
    lon = np.array([p[0] for p in points])
    lat = np.array([p[1] for p in points])
    ex, ey = plan.frame.to_xy(lon, lat)
    last = -1
    for x, y in zip(np.atleast_1d(ex), np.atleast_1d(ey), strict=True):
        d = np.hypot(st.x_m[last + 1 :] - x, st.y_m[last + 1 :] - y)
        hits = np.nonzero(d <= radius[last + 1 :])[0]
        if hits.size:
            last = last + 1 + int(hits[0])
    if last < 0:
        raise InputError(
            f"{path}: none of its {len(points)} camera events lies at a station of this plan; is it the "
            f"record of this mission? Give the station with --resume-from"
        )
    return last
