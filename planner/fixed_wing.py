"""What a plane can fly: turn radius, line order, turns, take-off and landing.

- Turn radius of a coordinated level turn: ``r = v^2 / (g tan(bank))`` (v the speed, bank the
  plane's bank limit, [vehicle] ``bank_limit_deg``). Two lines flown one after the other in
  opposite directions are joined by a U-turn of diameter ``2 r``.
- Line order: when the line spacing is at least ``2 r`` the lines are flown in the usual
  back-and-forth order. Otherwise in a lane-skipping order, as Mission Planner's survey grid does
  with its "minimum lane separation" (its Grid.cs: after each line the next is the nearest one
  at least that separation away; the first line is exempt): after each line the next is the
  nearest line not yet flown whose distance is at least ``2 r``.
- Where no line is far enough (few lines left, a narrow block), the plane flies a loop: a
  "light bulb" turn of three arcs of radius r (away from the next line, around, and onto it),
  written as waypoints every :data:`LOOP_STEP_DEG` of arc.
- Run-in (the straight approach before the first photo of a line): the autopilot steers onto
  a line with its L1 guidance, whose cross-track error behaves as a second-order system of
  natural period P (ArduPlane NAVL1_PERIOD, 17 s by default; PX4 FW_L1_PERIOD, 20 s) and damping
  0.75: it does not settle within a turn radius but over about a period of flight. The plane
  leaves its turn within the L1 distance ``L1 = 0.75 P v / pi`` of the line (the guidance's
  capture), and one period later the error's envelope ``exp(-2 pi 0.75 t / P)`` is below 1 % of
  it, so the run-in is ``max(v P, 2 r)`` (v the fastest speed flown, r the turn radius): under
  a metre off for the L1 distance of tens of metres a survey plane starts from. The lead-out
  after the last photo stays ``r``: the plane needs only to be out of the line before it turns.
- The first line after take-off: the plane climbs out on the take-off course and then flies to
  the first line's entry; when the entry lies within the climb-out and the turn that follows it
  (``climb_out_m + 2 r`` from home), its run-in grows until the entry lies beyond them, so the
  plane reaches its altitude and has turned before it starts the run-in.
- Take-off: NAV_TAKEOFF with param1 the minimum pitch (ArduPlane: TKOFF pitch, "Minimum pitch
  (plane)"; PX4: the same for fixed-wing take-off), its position ahead of home on the take-off
  course (PX4 flies toward it; ArduPlane takes off along its heading and ignores it).
- Landing: DO_LAND_START (the landing sequence ArduPlane's and PX4's RTL and "land" jump to),
  NAV_LOITER_TO_ALT at the approach point (param1 1: leave the loiter heading for the next
  waypoint, param2 the loiter radius, param4 1: leave it on the tangent), NAV_LAND at home. The
  approach point lies ``approach altitude / tan(glide slope)`` before home on the landing course,
  so the descent from it to the touchdown point follows the glide slope (the QGC fixed-wing
  landing pattern: DO_LAND_START, NAV_LOITER_TO_ALT, NAV_LAND).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .errors import SpecError
from .mission import MavCmd, MavFrame, MissionItem, VehicleType

if TYPE_CHECKING:  # planner.spec checks the fixed-wing keys with this module's functions
    from .spec import MissionSpec

#: Standard gravity, m/s2.
G_M_S2 = 9.80665
#: Bank limits a survey plane can hold: below 10 degrees it barely turns, above 60 the load
#: factor passes 2 g (ArduPlane's ROLL_LIMIT_DEG defaults to 45).
MIN_BANK_DEG = 10.0
MAX_BANK_DEG = 60.0
#: The fastest airspeed sfap plans for a survey plane, m/s (camera blur sets a lower one anyway).
MAX_AIRSPEED_M_S = 40.0
#: Period of the autopilot's L1 guidance, s: ArduPlane NAVL1_PERIOD and PX4 FW_L1_PERIOD defaults.
L1_PERIOD_S = {"ardupilot": 17.0, "px4": 20.0}
#: Damping ratio of the L1 guidance (ArduPlane NAVL1_DAMPING, PX4 FW_L1_DAMPING defaults).
L1_DAMPING = 0.75
#: Arc between the waypoints of a loop turn, degrees.
LOOP_STEP_DEG = 30.0

Point2 = tuple[float, float]


def turn_radius_m(speed_m_s: float, bank_deg: float) -> float:
    """Radius of a coordinated level turn at ``speed_m_s`` and ``bank_deg``: v^2 / (g tan(bank))."""
    return speed_m_s * speed_m_s / (G_M_S2 * math.tan(math.radians(bank_deg)))


def check_bank_limit(bank_deg: float, where: str) -> None:
    if not (MIN_BANK_DEG <= bank_deg <= MAX_BANK_DEG):
        load = 1.0 / math.cos(math.radians(min(abs(bank_deg), 89.9)))
        raise SpecError(
            f"{where}: bank_limit_deg = {bank_deg:g} is not a bank a survey plane flies (load factor "
            f"{load:.2f} g); set bank_limit_deg from {MIN_BANK_DEG:g} to {MAX_BANK_DEG:g} degrees "
            f"(the plane's roll limit, ArduPlane ROLL_LIMIT_DEG, 45 by default)"
        )


def check_speed_band(low_m_s: float, high_m_s: float, where: str) -> None:
    if low_m_s <= 0.0:
        raise SpecError(
            f"{where}: airspeed_min_m_s = {low_m_s:g}: a plane needs a positive minimum airspeed "
            f"(above its stall speed); set it, e.g. 9 (ArduPlane AIRSPEED_MIN)"
        )
    if high_m_s > MAX_AIRSPEED_M_S or high_m_s <= low_m_s:
        raise SpecError(
            f"{where}: airspeed_max_m_s = {high_m_s:g} with airspeed_min_m_s = {low_m_s:g}: give a "
            f"band with the maximum above the minimum and at most {MAX_AIRSPEED_M_S:g} m/s"
        )


def check_survey_speed(speed_m_s: float, low_m_s: float, high_m_s: float, where: str) -> None:
    """A plane flies its survey within its airspeed band (no hovering, no crawling)."""
    if not (low_m_s <= speed_m_s <= high_m_s):
        raise SpecError(
            f"{where}: speed_m_s = {speed_m_s:g} is outside the plane's airspeed band "
            f"{low_m_s:g} to {high_m_s:g} m/s (airspeed_min_m_s, airspeed_max_m_s in [vehicle]); "
            f"set speed_m_s within it"
        )


@dataclass(frozen=True, kw_only=True)
class FixedWing:
    """How a plane flies a plan: its turn radius and take-off and landing figures."""

    radius_m: float
    #: The fastest speed flown (m/s) and the autopilot's L1 period (s): the run-in.
    speed_m_s: float
    l1_period_s: float
    takeoff_pitch_deg: float
    glide_slope_deg: float
    approach_alt_m: float
    #: Grid bearing flown on the final approach (and the take-off course); None: from the survey.
    landing_heading_grid_deg: float | None

    @property
    def lead_in_m(self) -> float:
        """The run-in before a line's first photo: one L1 period of flight, at least a U-turn's
        width (module docstring)."""
        return max(self.speed_m_s * self.l1_period_s, 2.0 * self.radius_m)

    @property
    def lead_out_m(self) -> float:
        return self.radius_m

    @property
    def l1_distance_m(self) -> float:
        return L1_DAMPING * self.l1_period_s * self.speed_m_s / math.pi

    @property
    def climb_out_m(self) -> float:
        """How far the plane flies on its take-off course before it reaches the take-off
        altitude (climbing at the take-off pitch)."""
        return self.approach_alt_m / math.tan(math.radians(self.takeoff_pitch_deg))

    def first_lead_in_m(self, home_xy: Point2, start_xy: Point2, heading_deg: float) -> float:
        """The run-in of the first line after take-off, whose first photo is at ``start_xy``
        flown on grid bearing ``heading_deg``: at least :attr:`lead_in_m`, and long enough that
        the entry lies beyond the climb-out and the turn after it (module docstring)."""
        h = math.radians(heading_deg)
        back = (-math.sin(h), -math.cos(h))  # from the start toward the entry
        clear = self.climb_out_m + 2.0 * self.radius_m
        rx, ry = start_xy[0] - home_xy[0], start_xy[1] - home_xy[1]
        # the smallest s >= lead_in with |start + s back - home| >= clear
        b = rx * back[0] + ry * back[1]
        c = rx * rx + ry * ry - clear * clear
        disc = b * b - c
        lead = self.lead_in_m
        if disc > 0.0:
            s_in, s_out = -b - math.sqrt(disc), -b + math.sqrt(disc)
            if s_in < lead < s_out:
                lead = s_out
        return lead

    @property
    def loiter_radius_m(self) -> float:
        """Loiter at the approach point a little wider than the tightest turn."""
        return math.ceil(1.2 * self.radius_m)

    @property
    def approach_distance_m(self) -> float:
        return self.approach_alt_m / math.tan(math.radians(self.glide_slope_deg))

    def landing_course(self, home_xy: Point2, last_xy: Point2) -> tuple[float, float]:
        """Unit vector of the final approach (toward home)."""
        if self.landing_heading_grid_deg is not None:
            h = math.radians(self.landing_heading_grid_deg)
            return math.sin(h), math.cos(h)
        dx, dy = home_xy[0] - last_xy[0], home_xy[1] - last_xy[1]
        n = math.hypot(dx, dy)
        return (dx / n, dy / n) if n > 1e-6 else (0.0, 1.0)

    def approach_point(self, home_xy: Point2, last_xy: Point2) -> Point2:
        cx, cy = self.landing_course(home_xy, last_xy)
        d = self.approach_distance_m
        return home_xy[0] - cx * d, home_xy[1] - cy * d

    def takeoff_point(self, home_xy: Point2, first_xy: Point2) -> Point2:
        """Ahead of home on the take-off course (into the landing course's wind, or toward the
        survey), far enough for the climb at the take-off pitch."""
        if self.landing_heading_grid_deg is not None:
            h = math.radians(self.landing_heading_grid_deg)
            cx, cy = math.sin(h), math.cos(h)
        else:
            dx, dy = first_xy[0] - home_xy[0], first_xy[1] - home_xy[1]
            n = math.hypot(dx, dy)
            cx, cy = (dx / n, dy / n) if n > 1e-6 else (0.0, 1.0)
        d = max(2.0 * self.radius_m, self.approach_alt_m / math.tan(math.radians(self.takeoff_pitch_deg)))
        return home_xy[0] + cx * d, home_xy[1] + cy * d

    def landing_items(
        self, approach_latlon: tuple[float, float], home_latlon: tuple[float, float]
    ) -> list[MissionItem]:
        """DO_LAND_START, NAV_LOITER_TO_ALT at the approach point, NAV_LAND at home."""
        return [
            MissionItem(command=MavCmd.DO_LAND_START, frame=MavFrame.MISSION),
            MissionItem(
                command=MavCmd.NAV_LOITER_TO_ALT,
                param1=1.0,  # heading required: leave toward the next waypoint
                param2=self.loiter_radius_m,
                param3=0.0,
                param4=1.0,  # leave on the tangent
                param5=approach_latlon[0],
                param6=approach_latlon[1],
                param7=self.approach_alt_m,
            ),
            MissionItem(
                command=MavCmd.NAV_LAND,
                param1=0.0,  # abort altitude: the autopilot's default
                param5=home_latlon[0],
                param6=home_latlon[1],
                param7=0.0,
            ),
        ]

    def line_order(
        self, rows: Sequence[Sequence[int]], row_v_m: Sequence[float], first: tuple[bool, int]
    ) -> list[tuple[int, int]]:
        """(segment index, direction) in flight order: back and forth when the lines are at
        least 2 r apart, else Mission Planner's lane skipping (module docstring).

        ``rows`` lists per row (ascending v) its segments in ascending u; ``first`` is
        (start from the last row, first direction) as route.nearest_start gives them."""
        reverse, direction = first
        remaining = list(range(len(rows)))
        current = remaining[-1] if reverse else remaining[0]
        order: list[tuple[int, int]] = []
        diameter = 2.0 * self.radius_m
        while True:
            remaining.remove(current)
            members = list(rows[current]) if direction > 0 else list(reversed(rows[current]))
            order.extend((k, direction) for k in members)
            if not remaining:
                return order
            here = row_v_m[current]
            far = [r for r in remaining if abs(row_v_m[r] - here) >= diameter - 1e-6]
            pool = far or remaining
            current = min(pool, key=lambda r: (abs(row_v_m[r] - here), r))
            direction = -direction


def loop_turn(exit_xy: Point2, heading_deg: float, entry_xy: Point2, radius_m: float) -> list[Point2]:
    """Waypoints of the turn from a line left at ``exit_xy`` on grid bearing ``heading_deg`` to the
    next line, entered at ``entry_xy`` on the opposite bearing.

    Lines at least 2 r apart: two square corners (straight on first when the next line's entry
    lies ahead), each of which the plane rounds with its radius. Closer lines: a light-bulb loop
    of three arcs of radius r (away from the next line, around over the top, and onto it). An arc
    is written as the vertices of the polygon circumscribed about it (every
    :data:`LOOP_STEP_DEG` of arc): a plane that rounds each vertex with radius r flies the arc
    itself, and each leg is exactly as long as the two roundings at its ends need."""
    h = math.radians(heading_deg)
    f = np.array([math.sin(h), math.cos(h)])
    right = np.array([math.cos(h), -math.sin(h)])
    start = np.asarray(exit_xy, float)
    delta = np.asarray(entry_xy, float) - start
    lateral = float(delta @ right)
    ahead = float(delta @ f)
    d = abs(lateral)
    r = radius_m
    base = start + max(ahead, 0.0) * f
    if d >= 2.0 * r - 1e-9:
        corners = [base + lateral * right]
        if ahead > 1e-6:
            corners.insert(0, base)
        return [(float(p[0]), float(p[1])) for p in corners]
    side = 1.0 if lateral >= 0 else -1.0
    # Local frame: x toward the next line, y forward; start (0, 0) heading +y, end (d, 0) heading -y.
    yb = math.sqrt(max(4.0 * r * r - (d / 2.0 + r) ** 2, 0.0))
    theta = math.atan2(yb, d / 2.0 + r)
    arcs = (
        ((-r, 0.0), 0.0, theta),  # counterclockwise around A
        ((d / 2.0, yb), math.pi + theta, -theta),  # clockwise around B, over the top
        ((d + r, 0.0), math.pi - theta, math.pi),  # counterclockwise around C onto the line
    )
    local: list[tuple[float, float]] = [(0.0, 0.0)] if ahead > 1e-6 else []
    for (cx, cy), a0, a1 in arcs:
        n = max(1, math.ceil(abs(a1 - a0) / math.radians(LOOP_STEP_DEG)))
        step = (a1 - a0) / n
        reach = r / math.cos(step / 2.0)  # vertices of the circumscribed polygon
        for k in range(n):
            a = a0 + (k + 0.5) * step
            local.append((cx + reach * math.cos(a), cy + reach * math.sin(a)))
    local.append((d, 0.0))
    out = []
    for x, y in local:
        p = base + side * x * right + y * f
        out.append((float(p[0]), float(p[1])))
    return out


def fixed_wing_for(spec: MissionSpec, speed_m_s: float, true_north_grid_deg: float) -> FixedWing | None:
    """The plane of a spec flying at ``speed_m_s`` (None for other vehicles); refuses a speed
    outside its band. The turns are flown at the faster of the survey and transit speeds."""
    vehicle = spec.vehicle
    if vehicle.type is not VehicleType.FIXED_WING:
        return None
    where = f"{spec.source} [survey]"
    if spec.survey.trigger.value == "hover":
        raise SpecError(
            f'{where}: trigger = "hover" needs a vehicle that can hover; a plane triggers by distance: '
            f'use trigger = "distance"'
        )
    check_survey_speed(speed_m_s, vehicle.airspeed_min_m_s, vehicle.airspeed_max_m_s, where)
    transit = spec.survey.transit_speed_m_s
    if transit is not None:
        check_survey_speed(transit, vehicle.airspeed_min_m_s, vehicle.airspeed_max_m_s, where)
    fastest = max(speed_m_s, transit or 0.0)
    landing = vehicle.landing_heading_deg
    return FixedWing(
        radius_m=turn_radius_m(fastest, vehicle.bank_limit_deg),
        speed_m_s=fastest,
        l1_period_s=L1_PERIOD_S[vehicle.autopilot.value],
        takeoff_pitch_deg=vehicle.takeoff_pitch_deg,
        glide_slope_deg=vehicle.landing_glide_slope_deg,
        approach_alt_m=vehicle.takeoff_alt_m,
        landing_heading_grid_deg=None if landing is None else (landing + true_north_grid_deg) % 360.0,
    )
