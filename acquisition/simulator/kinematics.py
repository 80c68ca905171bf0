"""Kinematics of the simulated vehicle: where it is, how it moves along a leg, what its GPS reports.

The motion is exact and piecewise linear: every leg is a straight line flown at the commanded
horizontal speed, its vertical part limited by the climb or descent rate. Positions live in an
azimuthal equidistant frame centred on home (:class:`HomeFrame`; pyproj, WGS84), in which
distances from home are exact and local distances are correct to about 1e-6 within a few
kilometres.

The reported positions carry GPS noise (:class:`GpsNoise`): a smooth, seeded function of time
(a sum of sinusoids with periods 8-90 s, RMS ``horizontal_noise_m`` per axis and
``vertical_noise_m``), so it is deterministic and independent of the step size; the attitude
gets the same kind of noise.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pyproj import CRS, Transformer

from planner.geo import WGS84, LocalFrame
from planner.mission import HomePosition, VehicleType

from . import plane

if TYPE_CHECKING:
    from .flight import FlightSimulator

#: Above home by more than this (m), the vehicle is in the air.
AIRBORNE_ABOVE_M = 0.05


@dataclass
class Leg:
    """A straight move to ``target`` (x, y, z m, z above home), or a wait (target None)."""

    target: tuple[float, float, float] | None
    wait_s: float = 0.0
    forever: bool = False
    #: Flown as a plane flies it (:mod:`.plane`): L1 guidance along the track from
    #: ``track_from`` (None: from where the plane is when the leg starts), reached within
    #: ``accept_m`` or past the finish line.
    plane: bool = False
    track_from: tuple[float, float] | None = None
    accept_m: float = 0.0
    #: The climb rate of this leg (m/s) instead of the configured one (a plane's climb-out).
    climb_rate_m_s: float | None = None


def leg_duration_s(
    pos: tuple[float, float, float] | list[float],
    target: tuple[float, float, float],
    *,
    speed_m_s: float,
    climb_rate_m_s: float,
    descent_rate_m_s: float,
) -> float:
    """Seconds to fly from ``pos`` to ``target``: the horizontal part at ``speed_m_s``, the
    vertical part at the climb or descent rate, whichever takes longer."""
    dz = target[2] - pos[2]
    horizontal = math.hypot(target[0] - pos[0], target[1] - pos[1])
    vrate = climb_rate_m_s if dz > 0 else descent_rate_m_s
    if horizontal == 0.0 and dz == 0.0:
        return 0.0
    return max(horizontal / speed_m_s, abs(dz) / vrate)


class HomeFrame:
    """The azimuthal equidistant frame centred on ``home``: x east, y north, metres."""

    def __init__(self, home: HomePosition) -> None:
        crs = CRS.from_proj4(
            f"+proj=aeqd +lat_0={home.lat_deg!r} +lon_0={home.lon_deg!r} +datum=WGS84 +units=m +no_defs"
        )
        self.frame = LocalFrame.from_crs(crs)
        # scalar transforms, several times faster than the array API, for the telemetry
        self._lonlat_from_xy = Transformer.from_crs(crs, WGS84, always_xy=True)

    def xy(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        x, y = self.frame.to_xy(lon_deg, lat_deg)
        return float(x), float(y)

    def latlon(self, x: float, y: float) -> tuple[float, float]:
        """(latitude, longitude) in degrees of a point east/north of home in metres."""
        lon, lat = self._lonlat_from_xy.transform(x, y)
        return float(lat), float(lon)


class SmoothNoise:
    """A smooth seeded random function of time: a sum of sinusoids, RMS ``sigma``."""

    def __init__(self, rng: random.Random, sigma: float, n: int = 4) -> None:
        self.terms = [
            (rng.uniform(8.0, 90.0), rng.uniform(0.0, 2 * math.pi), rng.uniform(0.5, 1.0)) for _ in range(n)
        ]
        power = sum(a * a / 2 for _, _, a in self.terms)
        self.scale = sigma / math.sqrt(power) if power > 0 else 0.0

    def __call__(self, t_s: float) -> float:
        return self.scale * sum(a * math.sin(2 * math.pi * t_s / p + ph) for p, ph, a in self.terms)


class GpsNoise:
    """The seeded noise of the reported position (east, north, up) and attitude (roll, pitch,
    yaw); none on the ground."""

    def __init__(self, seed: int, horizontal_m: float, vertical_m: float, attitude_deg: float) -> None:
        rng = random.Random(seed)
        self._east = SmoothNoise(rng, horizontal_m)
        self._north = SmoothNoise(rng, horizontal_m)
        self._up = SmoothNoise(rng, vertical_m)
        self._attitude = [SmoothNoise(rng, attitude_deg) for _ in range(3)]

    def position(self, pos: list[float], t_s: float, airborne: bool) -> tuple[float, float, float]:
        """(x, y, z) reported for the true ``pos`` at simulated time ``t_s``."""
        return (
            pos[0] + self._east(t_s),
            pos[1] + self._north(t_s),
            pos[2] + (self._up(t_s) if airborne else 0.0),
        )

    def attitude_deg(
        self,
        vel: tuple[float, float, float],
        heading_deg: float,
        vehicle_type: VehicleType,
        t_s: float,
        airborne: bool,
    ) -> tuple[float, float, float]:
        """(roll, pitch, yaw) of a vehicle flying with velocity ``vel`` (east, north, up m/s):
        a multirotor pitches nose down to fly forward, a plane along its climb."""
        vx, vy, vz = vel
        speed = math.hypot(vx, vy)
        if vehicle_type is VehicleType.FIXED_WING:
            pitch = math.degrees(math.atan2(vz, speed)) if speed > 0 else 0.0
        else:
            pitch = -min(2.0 * speed, 25.0)
        noise = [n(t_s) if airborne else 0.0 for n in self._attitude]
        return noise[0], pitch + noise[1], (heading_deg + noise[2]) % 360.0


def advance(sim: FlightSimulator, dt: float) -> None:
    """Move ``sim`` for ``dt`` simulated seconds along its legs, the photos and the end of each
    leg at their exact times inside (a hold or a timed capture when it does not fly)."""
    end_time = sim.time_s + dt
    guard = 0
    while sim.time_s < end_time - 1e-12:
        guard += 1
        if guard > 100_000:
            break
        remaining = end_time - sim.time_s
        cap = sim.camera.next_capture_s - sim.time_s
        if not sim.flying_allowed() or not sim.legs:
            if sim.flying_allowed() and sim.after_legs is not None:
                sim.finish_legs()
                continue
            step = min(remaining, cap) if cap > 0 else 0.0
            sim.time_s += step
            sim.vel = (0.0, 0.0, 0.0)
            if sim.time_s >= sim.camera.next_capture_s - 1e-12:
                sim.timed_capture()
            continue
        leg = sim.legs[0]
        if leg.target is None:
            if leg.forever:
                step = min(remaining, cap) if cap > 0 else 0.0
            else:
                step = min(remaining, leg.wait_s, cap) if cap > 0 else 0.0
                leg.wait_s -= step
            sim.time_s += step
            sim.vel = (0.0, 0.0, 0.0)
            if not leg.forever and leg.wait_s <= 1e-12:
                sim.legs.pop(0)
            if sim.time_s >= sim.camera.next_capture_s - 1e-12:
                sim.timed_capture()
            continue
        if leg.plane:
            _plane_advance(sim, leg, remaining, cap)
            continue
        tx, ty, tz = leg.target
        dx, dy, dz = tx - sim.pos[0], ty - sim.pos[1], tz - sim.pos[2]
        need = leg_duration_s(
            sim.pos,
            leg.target,
            speed_m_s=sim.speed_m_s,
            climb_rate_m_s=leg.climb_rate_m_s or sim.config.climb_rate_m_s,
            descent_rate_m_s=sim.config.descent_rate_m_s,
        )
        if need <= 1e-12:
            sim.pos = [tx, ty, tz]
            sim.legs.pop(0)
            continue
        step = min(remaining, need, cap) if cap > 0 else 0.0
        frac = step / need
        start = (sim.pos[0], sim.pos[1])
        new = [sim.pos[0] + dx * frac, sim.pos[1] + dy * frac, sim.pos[2] + dz * frac]
        if frac >= 1.0 - 1e-12:
            new = [tx, ty, tz]
        if dx != 0.0 or dy != 0.0:
            sim.heading_deg = math.degrees(math.atan2(dx, dy)) % 360.0
        sim.vel = (dx / need, dy / need, dz / need)
        t0, z0 = sim.time_s, sim.pos[2]
        for s in sim.distance_trigger(start, (new[0], new[1])):
            sim.time_s = t0 + s * step
            sim.pos = [
                start[0] + (new[0] - start[0]) * s,
                start[1] + (new[1] - start[1]) * s,
                z0 + (new[2] - z0) * s,
            ]
            sim.take_photo()
        sim.pos = new
        sim.time_s = t0 + step
        if sim.pos[2] > AIRBORNE_ABOVE_M:
            sim.has_flown = True
        if frac >= 1.0 - 1e-12:
            sim.legs.pop(0)
        if sim.time_s >= sim.camera.next_capture_s - 1e-12:
            sim.timed_capture()
    sim.time_s = max(sim.time_s, end_time)


def _plane_advance(sim: FlightSimulator, leg: Leg, remaining: float, cap: float) -> None:
    """Fly ``leg`` as a plane (:mod:`.plane`) up to the next guidance update, the next photo
    or ``remaining`` seconds, whichever comes first; at an update, pop the leg if reached."""
    assert leg.target is not None
    tuning = sim.plane_tuning
    tx, ty, tz = leg.target
    here = (sim.pos[0], sim.pos[1])
    if leg.track_from is None:
        leg.track_from = here
    tick = round(sim.time_s / plane.NAV_PERIOD_S)
    on_grid = abs(sim.time_s - tick * plane.NAV_PERIOD_S) < 1e-9
    if on_grid and sim.plane_tick != tick:
        # the navigation update: is the waypoint reached, then the bank for the next period
        if math.dist(here, (tx, ty)) <= leg.accept_m or plane.past_finish_line(
            here, leg.track_from, (tx, ty)
        ):
            sim.legs.pop(0)
            sim.plane_last_wp = (tx, ty)
            if sim.legs and sim.legs[0].plane and sim.legs[0].track_from is None:
                sim.legs[0].track_from = (tx, ty)
            return
        course = math.radians(sim.heading_deg)
        accel = plane.lateral_accel_m_s2(tuning, here, course, sim.speed_m_s, leg.track_from, (tx, ty))
        demand = plane.demanded_bank_rad(tuning, accel)
        # the bank held over this period: where the roll lag has brought it in one period
        sim.plane_bank_rad = plane.next_bank_rad(tuning, sim.plane_bank_rad, demand, plane.NAV_PERIOD_S)
        sim.plane_rate_rad_s = plane.turn_rate_rad_s(sim.plane_bank_rad, sim.speed_m_s)
        sim.plane_tick = tick
    next_update = (math.floor(sim.time_s / plane.NAV_PERIOD_S + 1e-9) + 1) * plane.NAV_PERIOD_S
    step = min(remaining, next_update - sim.time_s, cap if cap > 0 else 0.0)
    if step <= 0.0:
        if cap <= 0 and sim.time_s >= sim.camera.next_capture_s - 1e-12:
            sim.timed_capture()
        return
    dz = tz - sim.pos[2]
    vrate = (leg.climb_rate_m_s or sim.config.climb_rate_m_s) if dz > 0 else sim.config.descent_rate_m_s
    vz = math.copysign(min(vrate, abs(dz) / step), dz) if dz != 0.0 else 0.0
    course = math.radians(sim.heading_deg)
    new_xy, new_course = plane.arc(here, course, sim.plane_rate_rad_s, sim.speed_m_s, step)
    t0, z0 = sim.time_s, sim.pos[2]
    for s in sim.distance_trigger(here, new_xy):
        sim.time_s = t0 + s * step
        at, _ = plane.arc(here, course, sim.plane_rate_rad_s, sim.speed_m_s, s * step)
        sim.pos = [at[0], at[1], z0 + vz * step * s]
        sim.take_photo()
    sim.pos = [new_xy[0], new_xy[1], z0 + vz * step]
    sim.heading_deg = math.degrees(new_course) % 360.0
    v = sim.speed_m_s
    sim.vel = (v * math.sin(new_course), v * math.cos(new_course), vz)
    sim.time_s = t0 + step
    if sim.pos[2] > AIRBORNE_ABOVE_M:
        sim.has_flown = True
    if sim.time_s >= sim.camera.next_capture_s - 1e-12:
        sim.timed_capture()
