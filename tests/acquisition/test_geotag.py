"""Geotagging: matching (acquisition.matching), attitude math (acquisition.attitude),
interpolation (acquisition.interpolation), the whole job on real JPEGs and bad input
(acquisition.geotag).

Synthetic survey (seeded): 6 lines x 10 camera events every 2 s at 10 m/s, 25 m-radius turns
(about 10 s without events), positions at 10 Hz. Frames = events + a camera clock offset of
37.25 s + Gaussian jitter (sigma 50 ms), 4 frames dropped, 1 spurious frame added. Tolerances:
the offset within 0.03 s (about 4 sigma of a median of 56 residuals); positions within 0.05 m
(the track is straight and sampled without noise where the events are, so the only error is
the EXIF rounding of 0.3 mm and float arithmetic).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import exifread
import numpy as np
import pyexiv2
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from PIL import Image
from shared_data import SHARED_DATA

from acquisition import attitude, exif, geotag, interpolation, matching, sidecars
from acquisition import card as card_frames
from acquisition.attitude import CameraMount
from acquisition.errors import GeotagError
from acquisition.geotag_results import FrameStatus, GeotagOptions, OffsetSource
from acquisition.telemetry.model import AttitudeTrack, CameraEvents, FlightLog, PositionTrack, VehicleType
from planner.errors import InputError, OutputExistsError
from planner.geo import LocalFrame, geodesic_distance_m

GARFIELD = SHARED_DATA / "garfield_rgb"
SITL = SHARED_DATA / "ardupilot_sitl_plane"
ORIGIN_LON, ORIGIN_LAT = -93.0, 42.0
FRAME = LocalFrame.utm_for(ORIGIN_LON, ORIGIN_LAT)
START_S = 1_700_000_000.0  # 2023-11-14T22:13:20Z
TRUE_OFFSET_S = 37.25
JITTER_S = 0.05
DROPPED = (3, 17, 18, 41)
SPURIOUS_AFTER = 25  # a spurious frame 0.95 s after this event


# ============================================================================ synthetic flight


@dataclass(frozen=True)
class Flight:
    log: FlightLog
    event_xy: np.ndarray  # (N, 2) true positions at the events, local frame
    x0: float
    y0: float
    segments: list[tuple[float, float, tuple[float, ...]]]  # (start s, end s, params)
    speed_m_s: float

    def xy_at(self, t: float) -> tuple[float, float, float]:
        """True (x, y, heading_deg) at time t."""
        for start, end, params in self.segments:
            if start <= t <= end:
                dt = t - start
                if params[0] == 0.0:  # straight: (0, x, y_start, direction)
                    _, x, y, direction = params
                    return x, y + direction * self.speed_m_s * dt, 0.0 if direction > 0 else 180.0
                _, cx, cy, r, a0, sense = params  # turn: centre, radius, start angle, +-1
                a = a0 + sense * self.speed_m_s * dt / r
                heading = math.degrees(math.atan2(-sense * math.sin(a), sense * math.cos(a))) % 360.0
                return cx + r * math.cos(a), cy + r * math.sin(a), heading
        raise ValueError(t)


def survey_flight(
    *,
    lines: int = 6,
    per_line: int = 10,
    seed: int = 0,
    start_s: float = START_S,
    roll_deg: float = 20.0,
    speed: float = 10.0,
    spacing: float = 20.0,
) -> Flight:
    """A lawnmower survey in the local frame; events by distance with 20 ms timing noise."""
    radius = 25.0
    rng = np.random.default_rng(seed)
    length = spacing * per_line
    x_arr, y_arr = FRAME.to_xy(ORIGIN_LON, ORIGIN_LAT)
    x0, y0 = float(x_arr), float(y_arr)
    segments: list[tuple[float, float, tuple[float, ...]]] = []
    t = start_s
    event_t: list[float] = []
    for k in range(lines):
        direction = 1.0 if k % 2 == 0 else -1.0
        x = x0 + 2 * radius * k
        y_start = y0 if direction > 0 else y0 + length
        segments.append((t, t + length / speed, (0.0, x, y_start, direction)))
        event_t += [t + (spacing / 2 + spacing * i) / speed + rng.normal(0, 0.02) for i in range(per_line)]
        t += length / speed
        if k < lines - 1:
            y_end = y_start + direction * length
            # Right-hand turn at the top (clockwise), left-hand at the bottom, both toward +x.
            a0 = math.pi  # the turn starts at the line's end, west of the turn centre
            sense = -1.0 if direction > 0 else 1.0
            segments.append((t, t + math.pi * radius / speed, (1.0, x + radius, y_end, radius, a0, sense)))
            t += math.pi * radius / speed
    flight = Flight(
        log=FlightLog(path="synthetic", format="tlog"),
        event_xy=np.zeros((0, 2)),
        x0=x0,
        y0=y0,
        segments=segments,
        speed_m_s=speed,
    )
    sample_t = np.arange(start_s - 5.0, t + 5.0, 0.1) + 0.037
    sample_t = sample_t[(sample_t >= segments[0][0]) & (sample_t <= segments[-1][1])]
    xyh = np.array([flight.xy_at(float(s)) for s in sample_t])
    lon, lat = FRAME.to_lonlat(xyh[:, 0], xyh[:, 1])
    in_turn = np.array([any(s0 < s < s1 and p[0] == 1.0 for s0, s1, p in segments) for s in sample_t])
    positions = PositionTrack(
        time_utc_s=sample_t,
        lat_deg=lat,
        lon_deg=lon,
        alt_amsl_m=np.full(sample_t.size, 300.0) + 0.01 * (sample_t - start_s),
        alt_rel_home_m=np.full(sample_t.size, 80.0),
        source="synthetic",
    )
    attitudes = AttitudeTrack(
        time_utc_s=sample_t,
        roll_deg=np.where(in_turn, roll_deg, 0.0),
        pitch_deg=np.full(sample_t.size, 3.0),
        yaw_deg=xyh[:, 2],
        source="synthetic",
    )
    et = np.array(event_t)
    exy = np.array([flight.xy_at(float(s))[:2] for s in et])
    elon, elat = FRAME.to_lonlat(exy[:, 0], exy[:, 1])
    events = CameraEvents(
        time_utc_s=et,
        seq=np.arange(1, et.size + 1, dtype=np.int64),
        lat_deg=elat + rng.normal(0, 1e-6, et.size),  # the autopilot's own (stale) position
        lon_deg=elon,
        source="synthetic",
    )
    log = FlightLog(path="synthetic", format="tlog", events=events, positions=positions, attitudes=attitudes)
    return replace(flight, log=log, event_xy=exy)


def frame_times(flight: Flight, *, seed: int = 1) -> tuple[np.ndarray, list[int | None]]:
    """Capture times (camera clock) and, per frame, the true event index (None: spurious)."""
    events = flight.log.events
    assert events is not None
    rng = np.random.default_rng(seed)
    times = events.time_utc_s + TRUE_OFFSET_S + rng.normal(0, JITTER_S, len(events))
    truth: list[int | None] = [j for j in range(len(events)) if j not in DROPPED]
    kept = [float(times[j]) for j in truth if j is not None]
    kept.append(float(events.time_utc_s[SPURIOUS_AFTER] + TRUE_OFFSET_S + 0.95))
    truth.append(None)
    order = np.argsort(kept)
    return np.array(kept)[order], [truth[k] for k in order]


_BASE_JPEG: bytes | None = None


def _base_jpeg() -> bytes:
    global _BASE_JPEG
    if _BASE_JPEG is None:
        pixels = np.random.default_rng(0).integers(0, 256, size=(32, 48, 3), dtype=np.uint8)
        buffer = io.BytesIO()
        Image.fromarray(pixels).save(buffer, format="JPEG", quality=85)
        _BASE_JPEG = buffer.getvalue()
    return _BASE_JPEG


def write_frame(path: Path, capture_s: float | None, *, sub_seconds: bool = True) -> Path:
    """A tiny real JPEG whose DateTimeOriginal/SubSecTimeOriginal say ``capture_s`` (ms); without
    ``sub_seconds`` the time is truncated to the second, as many cameras do."""
    image = pyexiv2.ImageData(_base_jpeg())
    tags = {"Exif.Image.Make": "TestCam", "Exif.Image.Model": "T1"}
    if capture_s is not None:
        whole = math.floor(capture_s)
        millis = round((capture_s - whole) * 1000)
        if millis == 1000:
            whole, millis = whole + 1, 0
        moment = np.datetime64(int(whole), "s").astype(object)
        tags["Exif.Photo.DateTimeOriginal"] = moment.strftime("%Y:%m:%d %H:%M:%S")
        if sub_seconds:
            tags["Exif.Photo.SubSecTimeOriginal"] = f"{millis:03d}"
    image.modify_exif(tags)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(image.get_bytes())
    image.close()
    return path


def write_frames(folder: Path, times: np.ndarray, *, sub_seconds: bool = True) -> list[Path]:
    return [
        write_frame(folder / f"DSC{k + 1:05d}.JPG", float(t), sub_seconds=sub_seconds)
        for k, t in enumerate(times)
    ]


def _exifread_position(path: Path) -> tuple[float, float, float]:
    with path.open("rb") as handle:
        tags = exifread.process_file(handle, details=False)

    def dms(key: str) -> float:
        v = [float(x.num) / float(x.den) for x in tags[key].values]
        return v[0] + v[1] / 60 + v[2] / 3600

    lat = dms("GPS GPSLatitude") * (-1 if str(tags["GPS GPSLatitudeRef"]) == "S" else 1)
    lon = dms("GPS GPSLongitude") * (-1 if str(tags["GPS GPSLongitudeRef"]) == "W" else 1)
    a = tags["GPS GPSAltitude"].values[0]
    alt = float(a.num) / float(a.den) * (-1 if tags["GPS GPSAltitudeRef"].values[0] == 1 else 1)
    return lat, lon, alt


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def flight() -> Flight:
    return survey_flight()


# ============================================================================ matching (pure)


def test_matcher_finds_offset_dropped_and_extra(flight: Flight) -> None:
    times, truth = frame_times(flight)
    events = flight.log.events
    assert events is not None
    m = matching.match_frames_to_events(times, events.time_utc_s)
    assert abs(m.offset_s - TRUE_OFFSET_S) < 0.03
    assert sorted(m.unmatched_events.tolist()) == list(DROPPED)
    assert m.unmatched_frames.tolist() == [truth.index(None)]
    for frame_index, event_index in m.pairs:
        assert truth[frame_index] == event_index
    assert len(m.pairs) == len(events) - len(DROPPED)
    assert not m.ambiguous
    assert 0.5 * JITTER_S < m.residual_mad_s < 2 * JITTER_S
    assert m.drift_ppm == 0.0  # 2 min of flight: no significant drift


def test_matcher_input_order_does_not_matter(flight: Flight) -> None:
    times, truth = frame_times(flight)
    events = flight.log.events
    assert events is not None
    perm = np.random.default_rng(5).permutation(times.size)
    m = matching.match_frames_to_events(times[perm], events.time_utc_s[::-1])
    n_events = len(events)
    for frame_index, event_index in m.pairs:
        assert truth[perm[frame_index]] == n_events - 1 - event_index


def test_matcher_estimates_drift_on_a_long_flight() -> None:
    long = survey_flight(lines=20, per_line=60, seed=3)  # 1200 events, about 45 min
    events = long.log.events
    assert events is not None
    rng = np.random.default_rng(9)
    drift = 40e-6  # a camera clock 40 ppm fast: 0.1 s over the flight
    t_mid = float(np.mean(events.time_utc_s))
    times = events.time_utc_s + TRUE_OFFSET_S + drift * (events.time_utc_s - t_mid)
    times = np.delete(times + rng.normal(0, 0.02, times.size), [10, 500, 501, 900])
    m = matching.match_frames_to_events(times, events.time_utc_s)
    assert m.drift_ppm == pytest.approx(40.0, abs=5.0)
    assert m.offset_s == pytest.approx(TRUE_OFFSET_S, abs=0.01)
    assert sorted(m.unmatched_events.tolist()) == [10, 500, 501, 900]
    assert m.unmatched_frames.size == 0


def test_regular_sequence_is_flagged_ambiguous() -> None:
    events = START_S + 2.0 * np.arange(30)
    m = matching.match_frames_to_events(events + 12.0, events)
    assert m.ambiguous and "--offset-s" in m.warnings[0]
    # Given the offset, that alignment is used and refined.
    given_m = matching.match_frames_to_events(events + 12.0, events, offset_s=14.0)
    assert given_m.offset_s == pytest.approx(14.0)
    assert given_m.pairs[:, 0].tolist() == list(range(1, 30))  # frame i on event i - 1
    assert given_m.pairs[:, 1].tolist() == list(range(29))


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    offset_s=st.floats(-7200.0, 7200.0),
    interval_s=st.floats(1.2, 4.0),
)
# Found by this test: one late frame at a line end made the alignment one interval off look
# better, confidently (before OUTLIER_COST and pricing with the larger scatter).
@example(seed=318967, offset_s=0.0, interval_s=2.0)
@example(seed=2061572043, offset_s=0.0, interval_s=1.6817546709707827)
def test_matcher_property_random_surveys(seed: int, offset_s: float, interval_s: float) -> None:
    """Any survey-like timeline (lines of regular triggers, pauses in the turns), any offset,
    jitter 30 ms, up to 10 % dropped frames and up to 2 spurious frames between events: every
    pair is right, and exactly the dropped events and the spurious frames are left over; or
    the matcher calls the alignment ambiguous and names the true offset among the competitors."""
    rng = np.random.default_rng(seed)
    events: list[float] = []
    t = START_S
    for _ in range(int(rng.integers(3, 8))):
        for _ in range(int(rng.integers(5, 16))):
            events.append(t)
            t += interval_s * (1 + rng.normal(0, 0.01))
        t += rng.uniform(6.0, 20.0)
    e = np.array(events)
    dropped = set(rng.choice(e.size, size=int(rng.integers(0, e.size // 10 + 1)), replace=False).tolist())
    frames = [(float(e[j] + offset_s + rng.normal(0, 0.03)), j) for j in range(e.size) if j not in dropped]
    for j in rng.choice(e.size - 1, size=int(rng.integers(0, 3)), replace=False):
        gap = e[j + 1] - e[j]
        frames.append((float(e[j] + offset_s + gap * rng.uniform(0.4, 0.6)), -1))
    frames.sort()
    f = np.array([t for t, _ in frames])
    truth = [j for _, j in frames]
    m = matching.match_frames_to_events(f, e)
    if m.ambiguous:  # then geotag writes nothing: the true offset must be one of those named
        named = [m.offset_s] + [o for o, _, _ in m.competitors]
        assert min(abs(o - offset_s) for o in named) < 0.05
        return
    assert all(truth[a] == b for a, b in m.pairs)
    assert set(m.unmatched_events.tolist()) == dropped
    assert [truth[k] for k in m.unmatched_frames] == [-1] * sum(1 for j in truth if j == -1)
    assert m.offset_s == pytest.approx(offset_s, abs=0.03)


def test_whole_second_capture_times(tmp_path: Path, flight: Flight) -> None:
    """A camera without sub-seconds truncates its times: taken at the middle of the second and
    matched with a tolerance widened by half a second; still every pair right."""
    times, truth = frame_times(flight)
    write_frames(tmp_path / "card", times, sub_seconds=False)
    result = geotag.geotag_images(tmp_path / "card", flight.log, tmp_path / "out", dry_run=True)
    assert any("whole seconds only" in w for w in result.warnings)
    names = [f"DSC{k + 1:05d}.JPG" for k in range(len(truth))]
    by_name = {f.name: f for f in result.frames}
    for name, j in zip(names, truth, strict=True):
        if j is not None:
            assert by_name[name].event_index == j
    assert [j for j, _ in result.unmatched_events] == list(DROPPED)
    assert result.offset_s == pytest.approx(TRUE_OFFSET_S, abs=0.15)


def test_offset_from_the_frames_own_gps_time(tmp_path: Path) -> None:
    """Without camera events and without --offset-s, frames that carry their own GPS time
    (the garfield Sequoia frames) give the camera clock offset: median 0.654 s."""
    originals = [exif.read_tags(p) for p in sorted(GARFIELD.glob("*.JPG"))]
    log = FlightLog(
        path="t",
        format="csv",
        positions=PositionTrack(
            time_utc_s=np.array([o.gps_time_utc_s for o in originals], float),
            lat_deg=np.array([o.gps_lat_deg for o in originals], float),
            lon_deg=np.array([o.gps_lon_deg for o in originals], float),
        ),
    )
    result = geotag.geotag_images(GARFIELD, log, tmp_path / "out", dry_run=True)
    assert result.offset_source is OffsetSource.EXIF_GPS
    assert result.offset_s == pytest.approx(0.6537, abs=1e-3)


def test_irreconcilable_sequences_raise() -> None:
    events = survey_flight(seed=0).log.events
    assert events is not None
    other_day = np.sort(np.random.default_rng(2).uniform(0, 200, 50)) + START_S + 86_400
    with pytest.raises(GeotagError, match=r"cannot be reconciled.*50 frames, 60 events"):
        matching.match_frames_to_events(other_day, events.time_utc_s)
    with pytest.raises(GeotagError, match=r"too few.*--offset-s"):
        matching.match_frames_to_events([START_S, START_S + 2], events.time_utc_s)
    with pytest.raises(GeotagError, match="nothing to match"):
        matching.match_frames_to_events([], events.time_utc_s)


# ============================================================================ attitude


@settings(max_examples=80, deadline=None)
@given(
    yaw=st.floats(0, 359.9),
    pitch=st.floats(-80, 80),
    roll=st.floats(-170, 170),
)
def test_euler_quaternion_round_trip(yaw: float, pitch: float, roll: float) -> None:
    y, p, r = attitude.euler_deg_from_quat(attitude.quat_from_euler_deg(yaw, pitch, roll))
    assert (float(y[0]) - yaw + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-6)
    assert float(p[0]) == pytest.approx(pitch, abs=1e-6)
    assert float(r[0]) == pytest.approx(roll, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    a=st.tuples(st.floats(0, 359), st.floats(-60, 60), st.floats(-60, 60)),
    b=st.tuples(st.floats(0, 359), st.floats(-60, 60), st.floats(-60, 60)),
    t=st.floats(0, 1),
)
def test_slerp_moves_at_constant_rate_along_the_short_arc(
    a: tuple[float, float, float], b: tuple[float, float, float], t: float
) -> None:
    qa, qb = attitude.quat_from_euler_deg(*a), attitude.quat_from_euler_deg(*b)

    def angle(q1: np.ndarray, q2: np.ndarray) -> float:
        return 2 * math.acos(min(1.0, abs(float(np.sum(q1 * q2)))))

    q = attitude.slerp(qa, qb, [t])
    total = angle(qa, qb)
    assert total <= math.pi + 1e-9
    assert angle(qa, q) == pytest.approx(t * total, abs=1e-6)
    assert angle(q, qb) == pytest.approx((1 - t) * total, abs=1e-6)


def test_slerp_wraps_yaw_through_north() -> None:
    q = attitude.slerp(attitude.quat_from_euler_deg(350, 0, 0), attitude.quat_from_euler_deg(10, 0, 0), [0.5])
    yaw, _, _ = attitude.euler_deg_from_quat(q)
    assert min(float(yaw[0]), 360 - float(yaw[0])) == pytest.approx(0.0, abs=1e-9)


def test_camera_attitude_with_gimbal() -> None:
    vehicle = ([30.0], [10.0], [-5.0])
    # No gimbal: a camera fixed to the airframe, looking down, carries the vehicle's angles.
    y, p, r = attitude.camera_attitude_deg(vehicle)
    assert (float(y[0]), float(p[0]), float(r[0])) == pytest.approx((30.0, 10.0, -5.0))
    # Earth-frame gimbal looking straight down, yaw 45: level camera, yaw 45.
    y, p, r = attitude.camera_attitude_deg(vehicle, ([45.0], [-90.0], [0.0]), attitude.GimbalMode.EARTH)
    assert (float(y[0]), float(p[0]), float(r[0])) == pytest.approx((45.0, 0.0, 0.0), abs=1e-9)
    # Stabilized: the gimbal yaw is relative to the nose.
    y, p, _ = attitude.camera_attitude_deg(vehicle, ([15.0], [-80.0], [0.0]), attitude.GimbalMode.STABILIZED)
    assert (float(y[0]), float(p[0])) == pytest.approx((45.0, 10.0), abs=1e-9)
    # Body: the gimbal turns with the airframe; pitch -90 on a 10 deg nose-up vehicle -> 10 deg.
    y, p, _ = attitude.camera_attitude_deg(
        ([0.0], [10.0], [0.0]), ([0.0], [-90.0], [0.0]), attitude.GimbalMode.BODY
    )
    assert (float(y[0]), float(p[0])) == pytest.approx((0.0, 10.0), abs=1e-9)


# ============================================================================ interpolation


def test_interpolation_on_a_straight_line(flight: Flight) -> None:
    events = flight.log.events
    assert events is not None and flight.log.positions is not None
    result = interpolation.interpolate_poses(
        events.time_utc_s, positions=flight.log.positions, attitudes=flight.log.attitudes
    )
    for k, pose in enumerate(result.poses):
        assert pose is not None
        lon, lat = FRAME.to_lonlat(*flight.event_xy[k])
        assert geodesic_distance_m(pose.lat_deg, pose.lon_deg, float(lat), float(lon)) < 0.01
        assert pose.position_gap_s == pytest.approx(0.1, abs=1e-6)
        assert pose.speed_m_s == pytest.approx(10.0, rel=1e-3)
        assert pose.yaw_deg is not None and pose.pitch_deg == pytest.approx(3.0)
        assert min(abs(pose.yaw_deg - 0.0), abs(pose.yaw_deg - 180.0), abs(pose.yaw_deg - 360)) < 1e-6


def test_interpolation_outside_and_in_gaps(flight: Flight) -> None:
    positions = flight.log.positions
    assert positions is not None
    keep = (positions.time_utc_s < START_S + 10) | (positions.time_utc_s > START_S + 20)
    holed = PositionTrack(
        time_utc_s=positions.time_utc_s[keep],
        lat_deg=positions.lat_deg[keep],
        lon_deg=positions.lon_deg[keep],
    )
    result = interpolation.interpolate_poses(
        [START_S - 100, START_S + 15, START_S + 5, float(positions.time_utc_s[-1]) + 60],
        positions=holed,
        max_gap_s=5.0,
    )
    assert result.poses[0] is None and "100.0 s before the log" in str(result.reasons[0])
    assert result.poses[1] is None and "gap of 10.1 s" in str(result.reasons[1])
    assert result.poses[2] is not None and result.poses[2].alt_amsl_m is None
    assert result.poses[2].yaw_deg is None  # no attitude track
    assert result.poses[3] is None and "after the log" in str(result.reasons[3])


# ============================================================================ the whole job


@pytest.fixture
def survey_images(tmp_path: Path, flight: Flight) -> tuple[Path, list[int | None]]:
    times, truth = frame_times(flight)
    write_frames(tmp_path / "card", times)
    return tmp_path / "card", truth


@pytest.mark.parametrize("from_events", [False, True], ids=["track", "event"])
def test_a_gimbal_camera_is_not_given_the_vehicles_pitch(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]], from_events: bool
) -> None:
    """Issue 24: a log with the vehicle's attitude (pitched 3 deg, rolled in the turns) and no
    gimbal angles. A camera on a stabilised gimbal (the default, as sfap's plans point it) looks
    straight down: pitch and roll 0 in the Pix4D convention, the vehicle's heading as yaw, and the
    result says which attitude it used. With --camera-mount fixed the camera takes the vehicle's
    attitude. The same from the track and from an event's own attitude (DataFlash CAM R, P, Y).
    The default (auto) follows what the log says the vehicle is (a fixed wing or a VTOL: fixed;
    a multirotor, or a log that does not say: gimbal), and the sentence says where the choice
    came from; an explicit mount wins over the log."""
    from acquisition.geotag_results import PositionSource

    card, truth = survey_images
    log = flight.log
    attitudes, events = log.attitudes, log.events
    assert attitudes is not None and events is not None and log.gimbal is None
    options: dict[str, object] = {}
    if from_events:  # the event carries the vehicle's attitude at the trigger
        yaw = np.interp(events.time_utc_s, attitudes.time_utc_s, np.unwrap(attitudes.yaw_deg, period=360.0))
        events = replace(
            events,
            roll_deg=np.interp(events.time_utc_s, attitudes.time_utc_s, attitudes.roll_deg),
            pitch_deg=np.full(len(events), 3.0),
            yaw_deg=np.mod(yaw, 360.0),
        )
        log = replace(log, events=events)
        options["position_source"] = PositionSource.EVENT
    heading = np.unwrap(attitudes.yaw_deg, period=360.0)
    cases = [
        (CameraMount.GIMBAL, VehicleType.FIXED_WING, CameraMount.GIMBAL, "; --camera-mount gimbal)"),
        (CameraMount.FIXED, VehicleType.MULTIROTOR, CameraMount.FIXED, "; --camera-mount fixed)"),
        (
            CameraMount.AUTO,
            None,
            CameraMount.GIMBAL,
            "the log does not say what the vehicle is: a gimbal assumed",
        ),
        (CameraMount.AUTO, VehicleType.MULTIROTOR, CameraMount.GIMBAL, "the log says a multirotor)"),
        (CameraMount.AUTO, VehicleType.FIXED_WING, CameraMount.FIXED, "the log says a fixed wing)"),
        (CameraMount.AUTO, VehicleType.VTOL, CameraMount.FIXED, "the log says a VTOL)"),
    ]
    for k, (asked, vehicle_type, mount, why) in enumerate(cases):
        result = geotag.geotag_images(
            card, replace(log, vehicle_type=vehicle_type), tmp_path / str(k), dry_run=True,
            options=GeotagOptions(camera_mount=asked, **options),  # type: ignore[arg-type]
        )  # fmt: skip
        said = [w for w in result.warnings if w.startswith("attitude:")]
        assert len(said) == 1 and "no gimbal angles" in said[0], result.warnings
        assert why in said[0], said
        matched = [f for f in result.frames if f.status is FrameStatus.MATCHED]
        assert len(matched) == len(truth) - 1
        for f in matched:
            assert f.yaw_deg is not None and f.pitch_deg is not None and f.roll_deg is not None
            assert f.time_utc_s is not None
            vehicle_yaw = float(np.interp(f.time_utc_s, attitudes.time_utc_s, heading))
            assert abs((f.yaw_deg - vehicle_yaw + 180.0) % 360.0 - 180.0) < 0.5, f
            if mount is CameraMount.GIMBAL:
                assert "stabilised gimbal" in said[0] and "--camera-mount fixed" in said[0]
                assert abs(f.pitch_deg) < 1e-9 and abs(f.roll_deg) < 1e-9, f
            else:
                assert "the vehicle's" in said[0]
                vehicle_roll = float(np.interp(f.time_utc_s, attitudes.time_utc_s, attitudes.roll_deg))
                assert f.pitch_deg == pytest.approx(3.0, abs=0.05)
                assert f.roll_deg == pytest.approx(vehicle_roll, abs=0.1)


def test_geotag_synthetic_survey(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    card, truth = survey_images
    before = {p.name: _sha(p) for p in card.iterdir()}
    calls: list[tuple[int, int]] = []
    result = geotag.geotag_images(
        card, flight.log, tmp_path / "out", progress=lambda d, t: calls.append((d, t))
    )
    names = [f"DSC{k + 1:05d}.JPG" for k in range(len(truth))]
    spurious = names[truth.index(None)]
    events = flight.log.events
    assert events is not None
    # The summary names the dropped frames (by event seq) and the extra frame.
    assert [seq for _, seq in result.unmatched_events] == [int(events.seq[j]) for j in DROPPED]
    assert result.extra_frames == (spurious,)
    assert result.offset_source is OffsetSource.MATCHED
    assert abs(result.offset_s - TRUE_OFFSET_S) < 0.03
    assert not result.untagged
    assert calls[-1] == (2 * len(names), 2 * len(names))
    by_name = {f.name: f for f in result.frames}
    worst_m = 0.0
    for name, j in zip(names, truth, strict=True):
        frame = by_name[name]
        out = tmp_path / "out" / name
        lat, lon, alt = _exifread_position(out)  # a second reader of what was written
        if j is None:
            assert frame.status is FrameStatus.EXTRA_BY_TIME
            # Placed at its own corrected time: error = speed x offset error (< 0.3 m).
            x, y, _ = flight.xy_at(float(frame.time_utc_s or 0))
            true_lon, true_lat = FRAME.to_lonlat(x, y)
            capture = float(frame.capture_time_s or 0)
            x_true, y_true, _ = flight.xy_at(capture - TRUE_OFFSET_S)
            assert math.hypot(x - x_true, y - y_true) < 0.3
            continue
        assert frame.status is FrameStatus.MATCHED and frame.event_index == j
        assert frame.event_seq == int(events.seq[j])
        assert frame.time_utc_s == events.time_utc_s[j]
        assert abs(frame.time_residual_s or 0) < 4 * JITTER_S
        true_lon, true_lat = FRAME.to_lonlat(*flight.event_xy[j])
        error = geodesic_distance_m(lat, lon, float(true_lat), float(true_lon))
        worst_m = max(worst_m, error)
        assert alt == pytest.approx(300.0 + 0.01 * (events.time_utc_s[j] - START_S), abs=0.002)
        heading = 0.0 if (j // 10) % 2 == 0 else 180.0
        assert frame.yaw_deg is not None and abs((frame.yaw_deg - heading + 180) % 360 - 180) < 1e-3
        assert exif.compressed_image_data(out) == exif.compressed_image_data(card / name)
    assert worst_m < 0.05
    # Originals untouched; nothing but the outputs in the folder.
    assert before == {p.name: _sha(p) for p in card.iterdir()}
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert written == sorted(
        [*names, "geo.txt", "pix4d_geolocation.csv", "cameras.geojson", "geotag_report.json"]
    )
    # Sidecars agree with the frames.
    crs, rows = sidecars.read_odm_geo_txt(tmp_path / "out" / "geo.txt")
    assert crs == "EPSG:4326" and [r.name for r in rows] == names
    for row in rows:
        assert row.lat_deg == pytest.approx(by_name[row.name].lat_deg, abs=1e-9)
        assert row.yaw_deg is not None and row.xy_accuracy_m is not None
    pix4d = sidecars.read_pix4d_csv(tmp_path / "out" / "pix4d_geolocation.csv")
    assert [(r.name, round(r.lon_deg, 9)) for r in pix4d] == [(r.name, round(r.lon_deg, 9)) for r in rows]
    features = json.loads((tmp_path / "out" / "cameras.geojson").read_text())["features"]
    assert len(features) == len(names) and features[0]["geometry"]["type"] == "Point"
    report = json.loads((tmp_path / "out" / "geotag_report.json").read_text())
    assert report["summary"]["extra_frames"] == [spurious]
    assert [e["seq"] for e in report["summary"]["unmatched_events"]] == [int(events.seq[j]) for j in DROPPED]


def test_a_frame_cut_short_is_tagged_and_named_in_the_report(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    """A frame whose end marker is missing (cut short on the card) is still tagged, its image
    data unchanged, and the report's warnings name it; the other frames are unaffected."""
    card, _ = survey_images
    cut = card / "DSC00007.JPG"
    whole = cut.read_bytes()
    assert whole.endswith(b"\xff\xd9")
    cut.write_bytes(whole[:-2])
    result = geotag.geotag_images(card, flight.log, tmp_path / "out")
    assert not result.untagged
    by_name = {f.name: f for f in result.frames}
    assert by_name["DSC00007.JPG"].status is FrameStatus.MATCHED
    assert [w for w in result.warnings if "DSC00007.JPG" in w], result.warnings
    written = (tmp_path / "out" / "DSC00007.JPG").read_bytes()
    start = written.index(b"\xff\xda")  # start of scan: everything from it on is the source's
    assert written[start:] == whole[whole.index(b"\xff\xda") : -2]
    lat, lon, _ = _exifread_position(tmp_path / "out" / "DSC00007.JPG")
    assert lat == pytest.approx(by_name["DSC00007.JPG"].lat_deg, abs=1e-7)
    assert lon == pytest.approx(by_name["DSC00007.JPG"].lon_deg, abs=1e-7)
    report = json.loads((tmp_path / "out" / "geotag_report.json").read_text())
    assert any("DSC00007.JPG" in w for w in report["summary"]["warnings"])


def test_geotag_by_time_without_events(tmp_path: Path, flight: Flight) -> None:
    events = flight.log.events
    assert events is not None
    times = events.time_utc_s[::3] + TRUE_OFFSET_S + np.random.default_rng(4).normal(0, JITTER_S, 20)
    write_frames(tmp_path / "card", times)
    track_only = replace(flight.log, events=None)
    result = geotag.geotag_images(tmp_path / "card", track_only, tmp_path / "out", offset_s=TRUE_OFFSET_S)
    assert result.offset_source is OffsetSource.GIVEN and not result.untagged
    for k, frame in enumerate(sorted(result.frames, key=lambda f: f.name)):
        assert frame.status is FrameStatus.BY_TIME
        true_lon, true_lat = FRAME.to_lonlat(*flight.event_xy[3 * k])
        lat, lon, _ = _exifread_position(tmp_path / "out" / frame.name)
        # Error = speed x jitter: 10 m/s x 50 ms sigma, 4 sigma bound.
        assert geodesic_distance_m(lat, lon, float(true_lat), float(true_lon)) < 4 * 10.0 * JITTER_S
    # Without --offset-s and without GPS time in the frames, the clock is assumed to be UTC:
    # every frame is then 37 s off and said so.
    wrong = geotag.geotag_images(tmp_path / "card", track_only, tmp_path / "out2", dry_run=True)
    assert wrong.offset_source is OffsetSource.ASSUMED_ZERO
    assert any("assumed to be UTC" in w for w in wrong.warnings)


def test_dry_run_writes_nothing(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    card, _ = survey_images
    result = geotag.geotag_images(card, flight.log, tmp_path / "out", dry_run=True)
    assert result.dry_run and len(result.tagged) == len(result.frames)
    assert not (tmp_path / "out").exists()
    assert all(f.output_path is None for f in result.frames)


def test_in_place_with_backup(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    card, _ = survey_images
    originals = {p.name: p.read_bytes() for p in card.iterdir()}
    with pytest.raises(InputError, match="--backup-dir"):
        geotag.geotag_images(card, flight.log, tmp_path / "out", in_place=True)
    result = geotag.geotag_images(
        card, flight.log, tmp_path / "out", in_place=True, backup_dir=tmp_path / "bak"
    )
    assert not result.untagged
    for name, data in originals.items():
        assert (tmp_path / "bak" / name).read_bytes() == data
        assert exif.read_tags(card / name).gps_lat_deg is not None
        assert exif.compressed_image_data(card / name) == exif.compressed_image_data(data)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(
        ["geo.txt", "pix4d_geolocation.csv", "cameras.geojson", "geotag_report.json"]
    )


def test_existing_output_needs_overwrite(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    card, _ = survey_images
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("keep me")
    with pytest.raises(OutputExistsError, match="--overwrite"):
        geotag.geotag_images(card, flight.log, out)
    assert (out / "old.txt").read_text() == "keep me"
    geotag.geotag_images(card, flight.log, out, overwrite=True)
    assert not (out / "old.txt").exists() and (out / "geo.txt").exists()


# ============================================================================ bad input


def test_bad_frames_are_listed_and_duplicate_names_kept_apart(tmp_path: Path, flight: Flight) -> None:
    """A card's DCIM folder: the camera restarted its numbering in 101MEDIA (normal on real cards),
    so DSC00001.JPG exists twice. Both are tagged, each with its own position, under names
    prefixed with their folder; nothing is overwritten."""
    times, truth = frame_times(flight)
    card = tmp_path / "card"
    write_frames(card / "100MEDIA", times[:30])
    write_frames(card / "101MEDIA", times[30:])  # the camera restarted its numbering
    write_frame(card / "101MEDIA" / "NOTIME.JPG", None)
    (card / "101MEDIA" / "BROKEN.JPG").write_bytes(b"\xff\xd8\xff\xe0garbage")
    (card / "101MEDIA" / "notes.txt").write_text("not an image")
    result = geotag.geotag_images(card, flight.log, tmp_path / "out")
    status = {f.name: f for f in result.frames}
    assert status["101MEDIA_NOTIME.JPG"].status is FrameStatus.NO_CAPTURE_TIME
    broken = status["101MEDIA_BROKEN.JPG"]
    assert broken.status is FrameStatus.UNREADABLE and "BROKEN.JPG" in str(broken.message)
    assert {f.name for f in result.untagged} == {"101MEDIA_NOTIME.JPG", "101MEDIA_BROKEN.JPG"}
    # Both DSC00001.JPG are tagged, each at its own event's position.
    events = flight.log.events
    assert events is not None
    for folder, k in (("100MEDIA", 0), ("101MEDIA", 30)):
        frame = status[f"{folder}_DSC00001.JPG"]
        assert frame.status is FrameStatus.MATCHED and frame.event_index == truth[k]
        assert Path(frame.source_path) == card / folder / "DSC00001.JPG"
        assert frame.output_path == str(tmp_path / "out" / f"{folder}_DSC00001.JPG")
    written = {p.name for p in (tmp_path / "out").iterdir() if p.suffix == ".JPG"}
    assert len(written) == len(times)
    geo_names = [line.split()[0] for line in (tmp_path / "out" / "geo.txt").read_text().splitlines()[1:]]
    assert len(geo_names) == len(set(geo_names)) == len(times)
    assert {"100MEDIA_DSC00001.JPG", "101MEDIA_DSC00001.JPG"} <= set(geo_names)
    # The matching used every timed frame: the same events are missing.
    assert [j for j, _ in result.unmatched_events] == list(DROPPED)


def test_unique_names_are_kept_as_they_are(tmp_path: Path, flight: Flight) -> None:
    times, _ = frame_times(flight)
    card = tmp_path / "card"
    write_frames(card / "100MEDIA", times[:3])
    paths = card_frames.list_images(card)
    assert card_frames.output_names(card, paths) == {p: p.name for p in paths}


def test_log_from_another_day(
    tmp_path: Path, flight: Flight, survey_images: tuple[Path, list[int | None]]
) -> None:
    card, _ = survey_images
    # Another day's flight, another pattern of events: nothing reconciles, nothing is written.
    other = survey_flight(seed=7, per_line=14, speed=12.0, spacing=25.0, start_s=START_S + 89_400.0)
    with pytest.raises(GeotagError, match="cannot be reconciled"):
        geotag.geotag_images(card, other.log, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    # A track only (no events): every frame lies outside the log; all listed, none written.
    result = geotag.geotag_images(card, replace(other.log, events=None), tmp_path / "out2", offset_s=0.0)
    assert len(result.untagged) == len(result.frames)
    assert all("before the log" in str(f.message) for f in result.untagged)
    assert any("another flight or day" in w for w in result.warnings)
    assert sorted(p.name for p in (tmp_path / "out2").iterdir()) == sorted(
        ["geo.txt", "pix4d_geolocation.csv", "cameras.geojson", "geotag_report.json"]
    )


def test_counts_that_cannot_be_reconciled(tmp_path: Path, flight: Flight) -> None:
    events = flight.log.events
    assert events is not None
    write_frames(tmp_path / "card", events.time_utc_s[:8] + TRUE_OFFSET_S)  # 8 frames
    few = CameraEvents(time_utc_s=events.time_utc_s[:60:20], seq=events.seq[:60:20])  # 3 events
    with pytest.raises(GeotagError, match="8 frames, 3 events"):
        geotag.geotag_images(tmp_path / "card", replace(flight.log, events=few), tmp_path / "out")


def test_empty_folder_and_missing_folder(tmp_path: Path, flight: Flight) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no JPEG images"):
        geotag.geotag_images(tmp_path / "empty", flight.log, tmp_path / "out")
    with pytest.raises(InputError, match="not a folder"):
        geotag.geotag_images(tmp_path / "missing", flight.log, tmp_path / "out")


def test_event_positions_used_when_the_track_is_missing(tmp_path: Path, flight: Flight) -> None:
    times, truth = frame_times(flight)
    write_frames(tmp_path / "card", times)
    events_only = replace(flight.log, positions=None, attitudes=None)
    result = geotag.geotag_images(tmp_path / "card", events_only, tmp_path / "out", dry_run=True)
    matched = [f for f in result.frames if f.status is FrameStatus.MATCHED]
    assert len(matched) == len(truth) - 1 and all(f.position_source == "event" for f in matched)
    extra = [f for f in result.frames if f.status is FrameStatus.EXTRA]
    assert [f.name for f in extra] == list(result.extra_frames) and "no camera event" in str(extra[0].message)


# ========================================================================= garfield (real frames)


@pytest.fixture(scope="module")
def garfield(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[exif.ImageTags]]:
    """Copies of the 28 real frames without GPS and attitude (read-only for the tests), and
    the original tags."""
    card = tmp_path_factory.mktemp("garfield") / "card"
    card.mkdir()
    originals = []
    for src in sorted(GARFIELD.glob("*.JPG")):
        originals.append(exif.read_tags(src))
        exif.strip_gps(src, card / src.name, attitude=True)
    return card, originals


def _garfield_track(originals: list[exif.ImageTags], *, gps_time: bool) -> FlightLog:
    t = np.array([(o.gps_time_utc_s if gps_time else o.capture_time_s) for o in originals], float)
    return FlightLog(
        path="garfield-tags",
        format="csv",
        positions=PositionTrack(
            time_utc_s=t,
            lat_deg=np.array([o.gps_lat_deg for o in originals], float),
            lon_deg=np.array([o.gps_lon_deg for o in originals], float),
            alt_amsl_m=np.array([o.gps_alt_amsl_m for o in originals], float),
        ),
        attitudes=AttitudeTrack(
            time_utc_s=t,
            roll_deg=np.array([o.camera_roll_deg for o in originals], float),
            pitch_deg=np.array([o.camera_pitch_deg for o in originals], float),
            yaw_deg=np.array([o.camera_yaw_deg for o in originals], float) % 360.0,
        ),
    )


def test_garfield_tags_recreated(tmp_path: Path, garfield: tuple[Path, list[exif.ImageTags]]) -> None:
    """Strip GPS and attitude from copies of the 28 real frames, build a track from the original
    tags keyed by capture time, geotag the copies by time, compare with the originals."""
    card, originals = garfield
    assert all(exif.read_tags(p).gps_lat_deg is None for p in card.iterdir())
    log = _garfield_track(originals, gps_time=False)
    result = geotag.geotag_images(
        card,
        log,
        tmp_path / "out",
        offset_s=0.0,
        # the Sequoia is fixed to the airframe: the track's attitude is the camera's
        options=GeotagOptions(max_gap_s=120.0, camera_mount=CameraMount.FIXED),
    )
    assert not result.untagged and len(result.frames) == 28
    worst_m = worst_alt_m = worst_yaw_deg = 0.0
    for original in originals:
        out = tmp_path / "out" / original.name
        lat, lon, alt = _exifread_position(out)
        assert original.gps_lat_deg is not None and original.gps_lon_deg is not None
        worst_m = max(worst_m, geodesic_distance_m(lat, lon, original.gps_lat_deg, original.gps_lon_deg))
        worst_alt_m = max(worst_alt_m, abs(alt - (original.gps_alt_amsl_m or 0.0)))
        back = exif.read_tags(out)
        assert back.camera_yaw_deg is not None and original.camera_yaw_deg is not None
        worst_yaw_deg = max(
            worst_yaw_deg, abs((back.camera_yaw_deg - original.camera_yaw_deg + 180) % 360 - 180)
        )
        assert back.camera_pitch_deg == pytest.approx(original.camera_pitch_deg, abs=1e-5)
        assert exif.compressed_image_data(out) == exif.compressed_image_data(GARFIELD / original.name)
    # Originals carry seconds to 1e-4 s (3 mm); ours to 1e-5 s: the difference is rounding only.
    assert worst_m < 0.005, worst_m
    assert worst_alt_m < 0.0005 and worst_yaw_deg < 1e-4


def test_garfield_from_gps_time_track_with_offset(
    tmp_path: Path, garfield: tuple[Path, list[exif.ImageTags]]
) -> None:
    """The harder variant: the track is keyed by the frames' GPS time stamps, which lag the
    camera clock by about 0.65 s; geotagging with that offset must land within 1 m (the offset
    scatters by about 20 ms between frames at about 12 m/s)."""
    card, originals = garfield
    log = _garfield_track(originals, gps_time=True)
    offset = float(np.median([o.capture_time_s - o.gps_time_utc_s for o in originals]))  # type: ignore[operator]
    assert 0.5 < offset < 0.8
    result = geotag.geotag_images(
        card, log, tmp_path / "out", offset_s=offset, options=GeotagOptions(max_gap_s=120.0)
    )
    errors = []
    for original in originals:
        f = next(fr for fr in result.frames if fr.name == original.name)
        assert f.lat_deg is not None and f.lon_deg is not None
        errors.append(
            geodesic_distance_m(f.lat_deg, f.lon_deg, original.gps_lat_deg or 0, original.gps_lon_deg or 0)
        )
    assert max(errors) < 1.0, max(errors)


@pytest.mark.slow
def test_pycolmap_creates_a_position_prior_for_every_tagged_frame(
    tmp_path: Path, garfield: tuple[Path, list[exif.ImageTags]]
) -> None:
    pycolmap = pytest.importorskip("pycolmap")
    stripped, all_originals = garfield
    card = tmp_path / "card"
    card.mkdir()
    originals = all_originals[:4]
    for original in originals:
        shutil.copy(stripped / original.name, card / original.name)
    log = _garfield_track(originals, gps_time=False)
    geotag.geotag_images(card, log, tmp_path / "out", offset_s=0.0, options=GeotagOptions(max_gap_s=120.0))
    images = tmp_path / "images"
    images.mkdir()
    for p in (tmp_path / "out").glob("*.JPG"):
        shutil.copy(p, images / p.name)
    database = tmp_path / "db.db"
    pycolmap.Database.open(database).close()  # an empty database
    pycolmap.import_images(database, images)
    db = pycolmap.Database.open(database)
    try:
        priors = db.read_all_pose_priors()
        names = {img.image_id: img.name for img in db.read_all_images()}
        frames = db.read_all_frames()
    finally:
        db.close()
    assert len(names) == 4 and len(priors) == 4
    by_name = {o.name: o for o in originals}
    image_of_frame = {}
    for frame in frames:
        for data_id in frame.data_ids:
            image_of_frame[frame.frame_id] = names[data_id.id]
    for prior in priors:
        assert prior.has_position()
        lat, lon, alt = (float(v) for v in prior.position)
        name = image_of_frame.get(prior.corr_data_id.id, names.get(prior.corr_data_id.id))
        assert name is not None
        original = by_name[name]
        assert lat == pytest.approx(original.gps_lat_deg, abs=1e-7)
        assert lon == pytest.approx(original.gps_lon_deg, abs=1e-7)
        assert alt == pytest.approx(original.gps_alt_amsl_m, abs=1e-3)


# ====================================================================== the real ArduPilot logs


@pytest.fixture(scope="module", params=["flight.tlog", "flight.BIN"])
def sitl_log(request: pytest.FixtureRequest) -> FlightLog:
    from acquisition.telemetry import read_log

    return read_log(SITL / request.param)


def test_real_autopilot_log(tmp_path: Path, sitl_log: FlightLog) -> None:
    """Frames made from the 70 real camera events of ArduPlane SITL (offset 23.5 s, jitter 50 ms,
    3 dropped, among them the first and the last, 1 spurious): found and named, without an
    ambiguity warning; every placed frame within 0.5 m of the position the autopilot itself
    logged with the event (its CAM position is its latest estimate, not interpolated from the
    track as ours is; measured: 0.13 m at worst from the tlog, 0.007 m from the DataFlash log)."""
    events = sitl_log.events
    assert events is not None and len(events) == 70
    rng = np.random.default_rng(11)
    times = events.time_utc_s + 23.5 + rng.normal(0, JITTER_S, 70)
    dropped = [0, 33, 69]
    kept = np.delete(times, dropped)
    spurious = float(events.time_utc_s[40] + 23.5 + 1.1)
    write_frames(tmp_path / "card", np.sort(np.append(kept, spurious)))
    # The plane's camera is fixed to the airframe (a servo-triggered camera, no gimbal): the
    # default mount follows the log, which says a fixed wing (pymavlink's reading of its
    # HEARTBEAT and MSG is the oracle in test_telemetry.py).
    result = geotag.geotag_images(tmp_path / "card", sitl_log, tmp_path / "out")
    said = [w for w in result.warnings if w.startswith("attitude:")]
    assert len(said) == 1 and "the vehicle's" in said[0] and "the log says a fixed wing" in said[0], said
    assert [j for j, _ in result.unmatched_events] == dropped
    assert len(result.extra_frames) == 1
    assert result.offset_s == pytest.approx(23.5, abs=0.03)
    assert events.lat_deg is not None and events.lon_deg is not None
    worst = 0.0
    for frame in result.frames:
        if frame.status is not FrameStatus.MATCHED:
            continue
        j = frame.event_index
        assert j is not None and frame.lat_deg is not None and frame.lon_deg is not None
        worst = max(
            worst,
            geodesic_distance_m(
                frame.lat_deg, frame.lon_deg, float(events.lat_deg[j]), float(events.lon_deg[j])
            ),
        )
    assert worst < 0.5, worst
    assert not any("ambiguous" in w for w in result.warnings)
    assert not result.untagged
    # The written camera attitude (no gimbal: the airframe's) against the attitude the
    # autopilot logged with each event (CAMERA_FEEDBACK / CAM roll, pitch, yaw). The tlog's
    # ATTITUDE arrives at 4 Hz and the plane also fires while rolling into its turns.
    assert events.roll_deg is not None and events.pitch_deg is not None and events.yaw_deg is not None
    diffs = np.array(
        [
            [
                f.roll_deg - events.roll_deg[f.event_index],
                f.pitch_deg - events.pitch_deg[f.event_index],
                (f.yaw_deg - events.yaw_deg[f.event_index] + 180.0) % 360.0 - 180.0,
            ]
            for f in result.frames
            if f.status is FrameStatus.MATCHED
            and f.event_index is not None
            and f.roll_deg is not None
            and f.pitch_deg is not None
            and f.yaw_deg is not None
        ]
    )
    assert diffs.shape == (67, 3)
    assert np.all(np.abs(diffs).max(axis=0) < (2.5, 0.6, 1.0)), np.abs(diffs).max(axis=0)
    assert np.all(np.median(np.abs(diffs), axis=0) < 0.1)


# ============================================================================ simulator, gimbal


@pytest.mark.slow
def test_simulated_flight_with_a_nadir_gimbal_keeps_the_heading(tmp_path: Path) -> None:
    """The issue's case: the bundled gully mission flown in the simulator (ArduPilot, gimbal
    commanded to -90, MOUNT_STATUS with the yaw relative to the nose). Every frame taken on a
    straight line is written looking straight down (pitch 0, roll 0) with its yaw on the course
    the vehicle flew, from the true shot positions before and after it. Before the fix, yaws
    were up to 149 deg off (median 39)."""
    from acquisition.simulator.server import SimulatedVehicle
    from acquisition.telemetry import read_log
    from planner.spec import load_spec
    from planner.survey import plan_survey

    repo = Path(__file__).resolve().parents[2]
    plan = plan_survey(load_spec(repo / "missions" / "bardenas-gully.toml"))
    tlog = tmp_path / "flight.tlog"
    vehicle = SimulatedVehicle(
        url="tcpin://127.0.0.1:0",
        autopilot=plan.mission.autopilot,
        speedup=400.0,
        tlog_path=tlog,
        home=plan.home,
        streams_on_request=False,  # no ground station asks for telemetry here: send it unasked
    )
    with vehicle:
        vehicle.load_mission(plan.mission.items)
        vehicle.auto_start()
        assert vehicle.wait_landed(timeout_s=120.0)
    log = read_log(tlog)
    assert log.gimbal is not None
    shots = vehicle.flight.shots
    assert {s.gimbal_pitch_deg for s in shots} == {-90.0}
    write_frames(tmp_path / "card", np.array([s.utc_s + 12.5 for s in shots]))
    result = geotag.geotag_images(tmp_path / "card", log, tmp_path / "out", dry_run=True)
    by_event = {f.event_index: f for f in result.frames if f.status is FrameStatus.MATCHED}
    assert len(by_event) == len(shots)
    checked = 0
    for k in range(1, len(shots) - 1):
        before, shot, after = shots[k - 1], shots[k], shots[k + 1]
        if not before.mission_seq == shot.mission_seq == after.mission_seq:
            continue  # a turn: no straight course to compare with
        course = math.degrees(math.atan2(after.x_m - before.x_m, after.y_m - before.y_m)) % 360.0
        frame = by_event[k]
        assert frame.yaw_deg is not None and frame.pitch_deg is not None and frame.roll_deg is not None
        assert abs((frame.yaw_deg - course + 180.0) % 360.0 - 180.0) < 3.0, (k, frame.yaw_deg, course)
        assert abs(frame.pitch_deg) < 1e-6 and abs(frame.roll_deg) < 1e-6
        checked += 1
    assert checked > 0.8 * len(shots)


# --- sync points without camera events (acquisition/geotag_offset.sync_offset_by_track) -------------


def _line_track(
    t0: float, *, seconds: int = 120, speed_m_s: float = 10.0, back_and_forth: bool = False
) -> FlightLog:
    """A track due east from (47.0 N, 8.0 E) at ``speed_m_s``, 1 Hz; with ``back_and_forth`` it
    turns at half time and flies back over the same ground (each place passed twice)."""
    frame = LocalFrame.utm_for(8.0, 47.0)
    x0, y0 = frame.to_xy(8.0, 47.0)
    t = np.arange(seconds, dtype=np.float64)
    half = seconds / 2.0
    x = speed_m_s * (np.where(t <= half, t, seconds - t) if back_and_forth else t)
    lon, lat = frame.to_lonlat(float(x0) + x, np.full_like(x, float(y0)))
    positions = PositionTrack(
        time_utc_s=t0 + t, lat_deg=np.asarray(lat, float), lon_deg=np.asarray(lon, float), source="test"
    )
    return FlightLog(path="track.csv", format="csv", positions=positions)


def test_a_sync_time_gives_the_camera_clock_minus_utc() -> None:
    """--sync FRAME=TIME without camera events: the offset is the camera's capture time minus the
    UTC time the crew gave, so that UTC = capture - offset places the frame at the time given."""
    from acquisition.geotag_offset import sync_offset_by_track
    from acquisition.sync_points import SyncPoint

    t0 = 1_700_000_000.0
    log = _line_track(t0)
    utc = t0 + 40.0
    capture = utc + 3600.0 + 7.5  # the camera an hour and 7.5 s ahead of UTC
    offset = sync_offset_by_track([(SyncPoint(frame="IMG_1.JPG", time_utc_s=utc), capture)], log)
    assert offset == pytest.approx(3607.5)
    assert capture - offset == pytest.approx(utc)


def test_a_sync_position_gives_the_time_the_track_passes_it() -> None:
    """--sync-position on a single pass: the offset is capture time minus the time the track is
    nearest the position (10 m/s due east: 300 m east is 30 s after the start)."""
    from acquisition.geotag_offset import sync_offset_by_track
    from acquisition.sync_points import SyncPoint

    t0 = 1_700_000_000.0
    log = _line_track(t0)
    frame = LocalFrame.utm_for(8.0, 47.0)
    x0, y0 = frame.to_xy(8.0, 47.0)
    lon, lat = frame.to_lonlat(float(x0) + 300.0, float(y0))
    point = SyncPoint(frame="IMG_2.JPG", lat_deg=float(lat), lon_deg=float(lon))
    offset = sync_offset_by_track([(point, t0 + 30.0 - 2.0)], log)
    assert offset == pytest.approx(-2.0, abs=0.05)


def test_a_sync_position_passed_twice_is_refused() -> None:
    """A flight that passes a sync position twice (out and back over it) cannot say which pass
    took the frame: refused, naming both passes, nothing guessed."""
    from acquisition.geotag_offset import sync_offset_by_track
    from acquisition.sync_points import SyncPoint

    t0 = 1_700_000_000.0
    log = _line_track(t0, back_and_forth=True)
    frame = LocalFrame.utm_for(8.0, 47.0)
    x0, y0 = frame.to_xy(8.0, 47.0)
    lon, lat = frame.to_lonlat(float(x0) + 200.0, float(y0))
    point = SyncPoint(frame="IMG_3.JPG", lat_deg=float(lat), lon_deg=float(lon))
    with pytest.raises(GeotagError, match=r"passes the sync position of IMG_3\.JPG 2 times"):
        sync_offset_by_track([(point, t0 + 20.0)], log)


def test_frames_on_the_track_samples_keep_the_track_speed() -> None:
    """A track sampled at the frames themselves (every time within 1 ms of a sample): each frame
    takes its sample's position, and its speed from the interval beside it, not 0."""
    t0 = 1_700_000_000.0
    log = _line_track(t0, seconds=20, speed_m_s=12.0)
    assert log.positions is not None
    times = log.positions.time_utc_s[[0, 5, 10, 19]] + np.array([0.0, 0.0004, -0.0009, 0.0])
    result = interpolation.interpolate_poses(times, positions=log.positions)
    for k, pose in enumerate(result.poses):
        assert pose is not None
        assert pose.speed_m_s == pytest.approx(12.0, rel=1e-3)
        assert pose.position_gap_s == 0.0
        sample = [0, 5, 10, 19][k]
        assert (
            geodesic_distance_m(
                pose.lat_deg, pose.lon_deg, log.positions.lat_deg[sample], log.positions.lon_deg[sample]
            )
            < 0.02
        )
