"""Sorties by endurance.

A plan longer than one battery is split into sorties, each a mission of its own that takes off
from home, flies a contiguous block of lines and returns home. The split is made at line
boundaries: the unit is a line (a camera-on run, with the runs of the same line that
planner.trigger cut and that follow each other without a turn), never part of one. Sorties are
filled greedily in the order of the lines across each pass (rows ascending, pass after pass), each
taking as many lines as fit; a sortie's time is the one planner.mission_builder estimates for it as
a whole (transit from home and back, climb and descent, turns, holds), so a sortie fits exactly
when the summary would say it fits. With ``scale_flight = "sorties"`` the passes of each height
([[survey.scale]]) are never mixed in one sortie.

Each sortie is built as a part of the plan (planner.partial); resume plans are planner.resume.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .errors import PlanningError, SpecError
from .lines import Segment
from .mission_builder import BuiltMission, PassPlan
from .partial import build_part, part_plan, plan_layout, segment_xy
from .plan import PlanLayout, SurveyPlan
from .summary import MAX_MISSION_ITEMS

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class Sortie:
    """One sortie: ``plan`` is a complete plan of its own (mission, stations, path, summary)."""

    number: int  # 1-based, the folder sortie-NN
    plan: SurveyPlan
    pass_indices: tuple[int, ...]  # the passes it flies (some of their lines)
    line_count: int

    def as_dict(self) -> dict[str, object]:
        s = self.plan.summary
        return {
            "sortie": self.number,
            "folder": sortie_folder(self.number),
            "passes": list(self.pass_indices),
            "line_count": self.line_count,
            "photo_count": s.photo_count,
            "flight_distance_m": s.flight_distance_m,
            "flight_time_s": s.flight_time_s,
            "item_count": s.item_count,
        }


def sortie_folder(number: int) -> str:
    return f"sortie-{number:02d}"


@dataclass(frozen=True)
class _Unit:
    """A line: consecutive joined runs of one row of one pass (indices into the pass's segments)."""

    pass_pos: int
    group: int  # passes of one height share a group when scales fly as their own sorties
    segments: tuple[int, ...]


def split_sorties(plan: SurveyPlan) -> list[Sortie]:
    """Split ``plan`` into sorties that each fit the vehicle's endurance less its reserve and the
    autopilot's mission capacity. Raises PlanningError when one line alone does not fit."""
    layout = plan_layout(plan)
    vehicle = layout.spec.vehicle
    usable_s = vehicle.usable_flight_s
    if usable_s is None:
        raise SpecError(
            f"{layout.spec.source}: splitting into sorties needs endurance_s (or battery_capacity_mah and "
            f"consumption_ma) in [vehicle]"
        )
    if usable_s <= 0:
        raise SpecError(
            f"{layout.spec.source}: the reserve leaves no flight time (endurance_s = "
            f"{vehicle.endurance_s:g}, reserve_pct = {vehicle.reserve_pct:g}, reserve_s = "
            f"{vehicle.reserve_s:g}); lower the reserve"
        )
    capacity = MAX_MISSION_ITEMS[vehicle.autopilot]
    units = _units(layout)
    cache: dict[tuple[int, int], tuple[BuiltMission, bool]] = {}

    def attempt(start: int, count: int) -> tuple[BuiltMission, bool]:
        key = (start, count)
        if key not in cache:
            built = build_part(plan, layout, _pass_plans(layout, units[start : start + count]))
            fits = built.flight_time_s <= usable_s + 1e-9 and len(built.mission.items) + 1 <= capacity
            cache[key] = (built, fits)
        return cache[key]

    chunks: list[tuple[int, int]] = []
    start = previous = 0
    while start < len(units):
        limit = 1
        while start + limit < len(units) and units[start + limit].group == units[start].group:
            limit += 1
        built, fits = attempt(start, 1)
        if not fits:
            raise PlanningError(_too_long(plan, layout, units[start], built, usable_s, capacity))
        # Galloping search from the last sortie's line count, then binary search, for the most
        # lines that fit (time grows with the lines); every count kept was built and fits.
        good, bad = 1, limit + 1
        guess = min(max(previous, 1), limit)
        if guess > 1:
            if attempt(start, guess)[1]:
                good = guess
            else:
                bad, step = guess, 1
                while bad - step > good:
                    if attempt(start, bad - step)[1]:
                        good = bad - step
                        break
                    bad -= step
                    step *= 2
        step = 1
        while bad == limit + 1 and good + step <= limit:
            if not attempt(start, good + step)[1]:
                bad = good + step
                break
            good += step
            step *= 2
        while bad - good > 1:
            mid = (good + bad) // 2
            if attempt(start, mid)[1]:
                good = mid
            else:
                bad = mid
        chunks.append((start, good))
        start += good
        previous = good
    sorties = []
    for number, (first, count) in enumerate(chunks, start=1):
        built, _ = attempt(first, count)
        chosen = units[first : first + count]
        sortie_plan = part_plan(
            plan, layout, built, f"{plan.name} sortie {number}", _pass_plans(layout, chosen), sortie=True
        )
        sorties.append(
            Sortie(
                number=number,
                plan=sortie_plan,
                pass_indices=tuple(sorted({layout.pass_plans[u.pass_pos].index for u in chosen})),
                line_count=len(chosen),
            )
        )
    log.info("split into %d sorties of at most %.0f s", len(sorties), usable_s)
    return sorties


def _too_long(
    plan: SurveyPlan, layout: PlanLayout, unit: _Unit, built: BuiltMission, usable_s: float, capacity: int
) -> str:
    pp = layout.pass_plans[unit.pass_pos]
    segs = [pp.segments[k] for k in unit.segments]
    length_m = sum(s.u_last_m - s.u_first_m for s in segs)
    vehicle = layout.spec.vehicle
    if len(built.mission.items) + 1 > capacity:
        return (
            f"{layout.spec.source}: line {segs[0].row} of the {pp.name} pass needs "
            f"{len(built.mission.items) + 1} mission items, more than {vehicle.autopilot.value} holds "
            f"({capacity}); split the area into smaller blocks"
        )
    reserve = f"endurance_s = {vehicle.endurance_s:g} s less the reserve ({vehicle.reserve_pct:g} %"
    reserve += f", at least {vehicle.reserve_s:g} s)" if vehicle.reserve_s else ")"
    return (
        f"{layout.spec.source}: line {segs[0].row} of the {pp.name} pass ({length_m:.0f} m of photos) "
        f"takes {built.flight_time_s / 60.0:.1f} min as a sortie of its own (from home and back, climb "
        f"and descent included), more than the {usable_s / 60.0:.1f} min one battery allows ({reserve}); "
        f"sorties are split only between lines: raise endurance_s (a larger battery) or lower the "
        f"reserve, take off nearer the area (home in [vehicle]), or split the area into shorter blocks"
    )


def _units(layout: PlanLayout) -> list[_Unit]:
    """The lines of every pass in the order sorties take them: pass by pass, rows ascending."""
    spec = layout.spec
    units: list[_Unit] = []
    groups: dict[float | None, int] = {}
    for pos, pp in enumerate(layout.pass_plans):
        height = pp.alt_agl_m if spec.survey.scale_flight == "sorties" else None
        group = groups.setdefault(height, len(groups))
        order = sorted(range(len(pp.segments)), key=lambda k: (pp.segments[k].row, pp.segments[k].u_first_m))
        if units and order and units[-1].group == group:
            # Take the rows of this pass from the end nearer the last line of the one before.
            last_pp = layout.pass_plans[units[-1].pass_pos]
            end = _centre(last_pp, last_pp.segments[units[-1].segments[-1]])
            first, last = _centre(pp, pp.segments[order[0]]), _centre(pp, pp.segments[order[-1]])
            if math.dist(end, last) < math.dist(end, first):
                order.reverse()
        current: list[int] = []
        for k in order:
            seg = pp.segments[k]
            if current:
                prev = pp.segments[current[-1]]
                low, high = (prev, seg) if prev.u_first_m < seg.u_first_m else (seg, prev)
                if prev.row == seg.row and low.join_hi and high.join_lo:
                    current.append(k)
                    continue
                units.append(_Unit(pass_pos=pos, group=group, segments=tuple(current)))
            current = [k]
        if current:
            units.append(_Unit(pass_pos=pos, group=group, segments=tuple(current)))
    return units


def _centre(pp: PassPlan, seg: Segment) -> tuple[float, float]:
    x, y = segment_xy(pp, seg)
    return float(x.mean()), float(y.mean())


def _pass_plans(layout: PlanLayout, units: Sequence[_Unit]) -> list[PassPlan]:
    chosen: dict[int, list[int]] = {}
    for u in units:
        chosen.setdefault(u.pass_pos, []).extend(u.segments)
    return [
        dataclasses.replace(pp, segments=tuple(pp.segments[k] for k in sorted(chosen.get(pos, []))))
        for pos, pp in enumerate(layout.pass_plans)
    ]


# --- writing ------------------------------------------------------------------------------------


def sorties_summary(plan: SurveyPlan, sorties: Sequence[Sortie]) -> dict[str, object]:
    """The "sorties" section of the combined summary.json."""
    vehicle = plan_layout(plan).spec.vehicle
    return {
        "endurance_s": vehicle.endurance_s,
        "reserve_pct": vehicle.reserve_pct,
        "reserve_s": vehicle.reserve_s,
        "usable_flight_s": vehicle.usable_flight_s,
        "count": len(sorties),
        "flight_time_s": float(sum(s.plan.summary.flight_time_s for s in sorties)),
        "flight_distance_m": float(sum(s.plan.summary.flight_distance_m for s in sorties)),
        "photo_count": int(sum(s.plan.summary.photo_count for s in sorties)),
        "list": [s.as_dict() for s in sorties],
    }


def write_with_sorties(
    plan: SurveyPlan,
    sorties: Sequence[Sortie],
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> list[Path]:
    """The whole plan's files in ``out_dir`` (its summary.json listing the sorties) and each
    sortie's own files in ``out_dir/sortie-NN/``; all or nothing."""
    import json

    from .outputs import atomic_write_text, staged_output_dir
    from .plan_folder import summary_json, write_outputs

    final = Path(out_dir)
    written: list[Path] = []
    with staged_output_dir(final, overwrite=overwrite) as staging:
        # The staging folder is empty: the whole plan goes into it as a folder of its own.
        names = [p.name for p in write_outputs(plan, staging, overwrite=True, progress=progress)]
        data = json.loads(summary_json(plan))
        data["sorties"] = sorties_summary(plan, sorties)
        atomic_write_text(staging / "summary.json", json.dumps(data, indent=2, allow_nan=False) + "\n")
        if "map.png" in names:  # the whole plan's map again, with the sorties drawn on it
            from .mapplot import render_map_png

            render_map_png(plan, staging / "map.png", sorties=[s.plan for s in sorties])
        written += [final / n for n in names]
        for sortie in sorties:
            folder = sortie_folder(sortie.number)
            names = [p.name for p in write_outputs(sortie.plan, staging / folder, progress=progress)]
            written += [final / folder / n for n in names]
    return written
