"""How the simulated plane flies a leg: ArduPlane's L1 guidance with a bank-limited turn.

A plane cannot be on its next line at once. ArduPlane (4.5) steers along the track from the
previous waypoint to the next with its L1 controller (libraries/AP_L1_Control,
``update_waypoint``), which asks for a lateral acceleration

    a = K_L1 v^2 / L1 sin(Nu),  K_L1 = 4 damping^2,  L1 = damping * period * v / pi,
    Nu = Nu1 + Nu2,  Nu2 = the angle of the velocity to the track,
    sin(Nu1) = cross-track error / L1 (limited to +-0.7071, a 45 degree capture angle),

with NAVL1_PERIOD 17 s and NAVL1_DAMPING 0.75 by default (far behind the track's start it
flies to the start; well past its end, to the end). The plane banks toward ``atan(a / g)``
within its roll limit (ROLL_LIMIT_DEG, 45 by default), the bank following the demand with the
roll controller's time constant (RLL2SRV_TCONST, 0.5 s by default: "time constant in seconds
from demanded to achieved roll angle"), and turns at ``g tan(bank) / v`` (a coordinated level
turn: radius ``v^2 / (g tan(bank))``). Linearised, the cross-track error obeys a
second-order system of natural period NAVL1_PERIOD and damping ratio NAVL1_DAMPING, so the plane
settles onto a new line over a few periods, not at once.

A waypoint is reached (Plane::verify_nav_wp) within ``turn_distance``: min(WP_RADIUS, L1) times
the coming turn's angle / 90 degrees (so the plane starts its turn before a corner), or once
past the line through the waypoint square to the track (past_interval_finish_line).

The guidance runs at a fixed rate (ArduPlane's navigate task, 10 Hz) on the absolute time
grid, the bank held between updates (where the roll lag has brought it), so within an update the
plane flies an exact circular arc (or a straight line) and a flight does not depend on how the
simulation's time is stepped. Not modelled: wind, the airspeed's changes in a turn, the
cross-track integrator (NAVL1_XTRACK_I), the height controller (the altitude changes at the
climb or descent rate). The same model flies PX4's planes (its L1 controller is the same law).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Standard gravity, m/s2.
G_M_S2 = 9.80665
#: ArduPlane's defaults (4.5): NAVL1_PERIOD s, NAVL1_DAMPING, ROLL_LIMIT_DEG, WP_RADIUS m.
L1_PERIOD_S = 17.0
L1_DAMPING = 0.75
ROLL_LIMIT_DEG = 45.0
WP_RADIUS_M = 90.0
#: The bank's response to a demand: first order, time constant in s (module docstring).
ROLL_LAG_S = 0.5
#: ArduPlane's navigation update period, s (navigate() at 10 Hz).
NAV_PERIOD_S = 0.1


@dataclass(frozen=True, kw_only=True)
class PlaneTuning:
    """The guidance parameters the simulated plane flies with (ArduPlane's defaults)."""

    l1_period_s: float = L1_PERIOD_S
    l1_damping: float = L1_DAMPING
    roll_limit_deg: float = ROLL_LIMIT_DEG
    wp_radius_m: float = WP_RADIUS_M
    #: Time constant of the bank's response to the demand, s (0: at once).
    roll_lag_s: float = ROLL_LAG_S

    def l1_distance_m(self, speed_m_s: float) -> float:
        """L1 = damping * period * v / pi (AP_L1_Control: 0.3183099 * damping * period * v)."""
        return self.l1_damping * self.l1_period_s * max(speed_m_s, 0.1) / math.pi

    def turn_distance_m(self, speed_m_s: float, turn_angle_deg: float) -> float:
        """How far before a waypoint the plane counts it reached (AP_L1_Control::turn_distance)."""
        base = min(self.wp_radius_m, self.l1_distance_m(speed_m_s))
        angle = abs(turn_angle_deg)
        return base * angle / 90.0 if angle < 90.0 else base

    @property
    def max_lateral_accel_m_s2(self) -> float:
        return G_M_S2 * math.tan(math.radians(self.roll_limit_deg))


def lateral_accel_m_s2(
    tuning: PlaneTuning,
    pos: tuple[float, float],
    course_rad: float,
    speed_m_s: float,
    prev_wp: tuple[float, float],
    next_wp: tuple[float, float],
) -> float:
    """The L1 controller's lateral acceleration demand (positive: turn right), unlimited.

    Positions x east, y north; ``course_rad`` the grid bearing flown (clockwise from north)."""
    v = max(speed_m_s, 0.1)
    k = 4.0 * tuning.l1_damping * tuning.l1_damping
    l1 = tuning.l1_distance_m(v)
    vx, vy = v * math.sin(course_rad), v * math.cos(course_rad)
    abx, aby = next_wp[0] - prev_wp[0], next_wp[1] - prev_wp[1]
    ab_len = math.hypot(abx, aby)
    if ab_len < 1e-6:
        abx, aby = next_wp[0] - pos[0], next_wp[1] - pos[1]
        ab_len = math.hypot(abx, aby)
        if ab_len < 1e-6:
            abx, aby, ab_len = math.sin(course_rad), math.cos(course_rad), 1.0
    ux, uy = abx / ab_len, aby / ab_len
    ax, ay = pos[0] - prev_wp[0], pos[1] - prev_wp[1]
    wp_a_dist = math.hypot(ax, ay)
    along = ax * ux + ay * uy
    seg_len = math.hypot(next_wp[0] - prev_wp[0], next_wp[1] - prev_wp[1])

    def toward(dx: float, dy: float) -> float:
        # the angle from the velocity to the vector (dx, dy), positive clockwise (a right turn)
        cross = vx * dy - vy * dx
        dot = vx * dx + vy * dy
        return -math.atan2(cross, dot)

    if wp_a_dist > l1 and along / max(wp_a_dist, 1.0) < -0.7071:
        nu = toward(-ax, -ay)  # far behind the start: fly to it
    elif along > seg_len + v * 3.0:
        nu = toward(next_wp[0] - pos[0], next_wp[1] - pos[1])  # well past the end: fly to it
    else:
        # cross-track error, positive when the plane is right of the track
        xtrack = ax * uy - ay * ux
        xtrack_vel = vx * uy - vy * ux
        ltrack_vel = vx * ux + vy * uy
        nu2 = -math.atan2(xtrack_vel, ltrack_vel)  # turn back when moving right
        sine_nu1 = max(-0.7071, min(0.7071, xtrack / max(l1, 0.1)))
        nu1 = -math.asin(sine_nu1)
        nu = nu1 + nu2
    nu = max(-math.pi / 2, min(math.pi / 2, nu))
    return k * v * v / l1 * math.sin(nu)


def demanded_bank_rad(tuning: PlaneTuning, accel_m_s2: float) -> float:
    """The bank of a coordinated turn with the demanded lateral acceleration, within the roll
    limit: atan(a / g) (positive: right)."""
    limit = math.radians(tuning.roll_limit_deg)
    return max(-limit, min(limit, math.atan(accel_m_s2 / G_M_S2)))


def next_bank_rad(tuning: PlaneTuning, bank_rad: float, demand_rad: float, dt_s: float) -> float:
    """The bank ``dt_s`` after an update, rolling toward the demand with the roll lag."""
    if tuning.roll_lag_s <= 0.0:
        return demand_rad
    return demand_rad + (bank_rad - demand_rad) * math.exp(-dt_s / tuning.roll_lag_s)


def turn_rate_rad_s(bank_rad: float, speed_m_s: float) -> float:
    """The turn rate of a coordinated level turn: g tan(bank) / v (positive: right)."""
    return G_M_S2 * math.tan(bank_rad) / max(speed_m_s, 0.1)


def arc(
    pos: tuple[float, float], course_rad: float, rate_rad_s: float, speed_m_s: float, dt_s: float
) -> tuple[tuple[float, float], float]:
    """Where a plane at ``pos`` on ``course_rad`` turning at ``rate_rad_s`` is after ``dt_s``
    (an exact circular arc), and its course then."""
    c1 = course_rad + rate_rad_s * dt_s
    if abs(rate_rad_s) < 1e-9:
        d = speed_m_s * dt_s
        return (pos[0] + d * math.sin(course_rad), pos[1] + d * math.cos(course_rad)), course_rad
    r = speed_m_s / rate_rad_s
    dx = r * (math.cos(course_rad) - math.cos(c1))
    dy = r * (math.sin(c1) - math.sin(course_rad))
    return (pos[0] + dx, pos[1] + dy), c1


def past_finish_line(pos: tuple[float, float], prev_wp: tuple[float, float], wp: tuple[float, float]) -> bool:
    """Past the line through ``wp`` square to the track prev_wp -> wp
    (Location::past_interval_finish_line)."""
    tx, ty = wp[0] - prev_wp[0], wp[1] - prev_wp[1]
    if math.hypot(tx, ty) < 1e-6:
        return True
    return (pos[0] - wp[0]) * tx + (pos[1] - wp[1]) * ty >= 0.0


def turn_angle_deg(a: tuple[float, float], b: tuple[float, float], c: tuple[float, float]) -> float:
    """The change of bearing at ``b`` from the track a -> b to b -> c, degrees (-180, 180]."""
    h1 = math.atan2(b[0] - a[0], b[1] - a[1])
    h2 = math.atan2(c[0] - b[0], c[1] - b[1])
    d = math.degrees(h2 - h1)
    return (d + 180.0) % 360.0 - 180.0
