"""The camera clock offset from the frames' motion against the track (acquisition.offset_from_images).

The misfit and its minimum on synthetic camera paths built here, independently of the code: a
vehicle flying a lawnmower pattern (or a single straight line) sampled by a track at 5 Hz,
frames taken at times shifted by a known offset, and a "reconstruction" that is the true camera
centres moved by a random similarity (and, in some tests, blurred by noise). The estimate must
recover the known offset, within its stated uncertainty, and refuse one when the geometry
cannot give it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from survey_frames import write_frame

from acquisition.offset_from_images import (
    FINE_STEP_S,
    ModelPath,
    TrackXYZ,
    aligned_rss,
    estimate_offset,
    frame_pairs,
    misfit,
)
from processing.similarity import fit_similarity

F64 = NDArray[np.float64]


def _rotation(rng: np.random.Generator) -> F64:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _lawnmower(
    rng: np.random.Generator,
    *,
    lines: int,
    speed: float,
    length: float,
    spacing: float,
    interval: float,
    wobble_m: float = 2.0,
    margin_s: float = 0.0,
) -> tuple[F64, F64, F64]:
    """(track times, track xyz, frame UTC times): ``lines`` lines of ``length`` m flown in
    alternating directions ``spacing`` m apart at ``speed`` m/s, joined by half-circle turns, a
    random heading and an altitude wobble of ``wobble_m``; frames every ``interval`` s on the lines
    only, from ``margin_s`` after a line's start to ``margin_s`` before its end."""
    heading = rng.uniform(0, 2 * math.pi)
    along = np.array([math.cos(heading), math.sin(heading)])
    across = np.array([-along[1], along[0]])
    nodes_t, nodes_xy, frames = [0.0], [np.zeros(2)], []
    t = 0.0
    position = np.zeros(2)
    for line in range(lines):
        direction = along if line % 2 == 0 else -along
        start = t
        steps = max(int(length / speed / 0.5), 2)
        for _ in range(steps):
            t += 0.5
            position = position + direction * speed * 0.5
            nodes_t.append(t)
            nodes_xy.append(position.copy())
        frames.extend(
            np.arange(start + margin_s + interval / 2, t - margin_s - interval / 2, interval).tolist()
        )
        if line + 1 < lines:  # a half circle to the next line
            radius = spacing / 2
            centre = position + across * radius
            turn_steps = max(int(math.pi * radius / speed / 0.5), 4)
            for k in range(1, turn_steps + 1):
                angle = math.pi * k / turn_steps
                offset = -across * math.cos(angle) * radius + direction * math.sin(angle) * radius
                t += 0.5
                nodes_t.append(t)
                nodes_xy.append(centre + offset)
            position = nodes_xy[-1].copy()
    # Lead-in and lead-out: the log runs before and after the photos.
    t_nodes = np.array(nodes_t)
    xy_nodes = np.array(nodes_xy)
    track_t = np.arange(-30.0, t + 30.0, 0.2)
    x = np.interp(track_t, t_nodes, xy_nodes[:, 0])
    y = np.interp(track_t, t_nodes, xy_nodes[:, 1])
    z = 100.0 + wobble_m * np.sin(track_t / 17.0)
    return track_t, np.column_stack([x, y, z]), np.array(frames)


def _model_of(
    rng: np.random.Generator, track: TrackXYZ, utc: F64, offset_s: float, noise_m: float
) -> ModelPath:
    """The true centres at ``utc`` moved by a random similarity (scale 0.01-10), plus noise."""
    centres = track.at(utc) + rng.normal(scale=noise_m, size=(len(utc), 3)) if noise_m else track.at(utc)
    scale = float(10 ** rng.uniform(-2, 1))
    moved = scale * centres @ _rotation(rng).T + rng.normal(scale=500.0, size=3)
    return ModelPath(names=tuple(f"f{k}" for k in range(len(utc))), capture_s=utc + offset_s, centres=moved)


survey = st.fixed_dictionaries(
    {
        "seed": st.integers(0, 2**32 - 1),
        "lines": st.integers(2, 5),
        "speed": st.floats(4.0, 20.0),
        "length": st.floats(150.0, 600.0),
        "spacing": st.floats(30.0, 120.0),
        "interval": st.floats(1.0, 4.0),
        "offset": st.floats(-40.0, 40.0),
    }
)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 40), st.floats(0.0, 5.0))
def test_closed_form_misfit_is_the_fitted_similarity_residual(seed: int, n: int, noise: float) -> None:
    """The closed-form misfit equals the residual sum of the similarity fitted by
    processing.similarity (an independent implementation: SVD of the weighted cross-covariance)."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=50.0, size=(n, 3))
    mirror = np.diag([1.0, 1.0, -1.0])  # the third target set is a mirror image: no rotation fits it
    targets = np.stack(
        [
            float(10 ** rng.uniform(-1, 1)) * centres @ (_rotation(rng) @ (mirror if k == 2 else np.eye(3))).T
            + rng.normal(scale=100.0, size=3)
            + rng.normal(scale=noise + 1e-3, size=(n, 3))
            for k in range(3)
        ]
    )
    closed = aligned_rss(centres, targets)
    for k in range(3):
        fitted = fit_similarity(centres, targets[k])
        residual = float(np.sum((fitted.apply(centres) - targets[k]) ** 2))
        assert closed[k] == pytest.approx(residual, rel=1e-6, abs=1e-6)


@settings(max_examples=40, deadline=None)
@given(survey)
def test_exact_centres_give_the_offset(case: dict[str, float]) -> None:
    """Noise-free centres: the misfit is zero at the true offset and the estimate finds it (to the
    fine scan's step), whatever similarity the reconstruction is in."""
    rng = np.random.default_rng(int(case["seed"]))
    t, xyz, frames = _lawnmower(
        rng,
        lines=int(case["lines"]),
        speed=case["speed"],
        length=case["length"],
        spacing=case["spacing"],
        interval=case["interval"],
    )
    assume(len(frames) >= 8)
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    model = _model_of(rng, track, frames, case["offset"], 0.0)
    assert misfit([model], track, case["offset"])[0] < 1e-12 * max(1.0, float(np.sum(xyz**2)))
    estimate = estimate_offset([model], track)
    assert estimate.best_offset_s is not None
    assert abs(estimate.best_offset_s - case["offset"]) <= FINE_STEP_S + 1e-9


@settings(max_examples=40, deadline=None)
@given(survey, st.floats(0.3, 3.0))
def test_noisy_centres_give_the_offset_within_its_uncertainty(case: dict[str, float], noise_m: float) -> None:
    """Centres blurred by noise of a few metres: the estimate (when claimed) lies within four
    of its stated sigmas of the true offset; when not claimed, the reason is given."""
    rng = np.random.default_rng(int(case["seed"]))
    t, xyz, frames = _lawnmower(
        rng,
        lines=int(case["lines"]),
        speed=case["speed"],
        length=case["length"],
        spacing=case["spacing"],
        interval=case["interval"],
    )
    assume(len(frames) >= 8)
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    estimate = estimate_offset([_model_of(rng, track, frames, case["offset"], noise_m)], track)
    if estimate.offset_s is None:
        assert estimate.reason
        return
    assert estimate.sigma_s is not None
    assert abs(estimate.offset_s - case["offset"]) <= 4.0 * estimate.sigma_s + FINE_STEP_S


def test_the_stated_sigma_matches_the_scatter_of_estimates() -> None:
    """Over many noise draws on one survey, the estimates scatter about the true offset as their
    stated sigma says (the sigma is neither a wild over- nor under-statement)."""
    rng = np.random.default_rng(7)
    t, xyz, frames = _lawnmower(rng, lines=4, speed=12.0, length=400.0, spacing=60.0, interval=2.0)
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    errors, sigmas = [], []
    for _ in range(40):
        estimate = estimate_offset([_model_of(rng, track, frames, -2.5, 2.0)], track)
        assert estimate.offset_s is not None and estimate.sigma_s is not None
        errors.append(estimate.offset_s + 2.5)
        sigmas.append(estimate.sigma_s)
    scatter = float(np.sqrt(np.mean(np.square(errors))))
    stated = float(np.median(sigmas))
    assert 0.5 * stated <= scatter <= 2.0 * stated, (scatter, stated)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(4.0, 20.0), st.floats(-20.0, 20.0))
def test_a_straight_line_at_constant_speed_claims_nothing(seed: int, speed: float, offset: float) -> None:
    """Frames in the middle of one straight line flown one way at constant speed and height (the
    line runs on 40 s before and after them): a shift in time is a translation along it, which the
    similarity absorbs; no offset is claimed, and the reason says the curve is flat."""
    rng = np.random.default_rng(seed)
    t, xyz, frames = _lawnmower(
        rng,
        lines=1,
        speed=speed,
        length=speed * 200.0,
        spacing=50.0,
        interval=2.0,
        wobble_m=0.0,
        margin_s=40.0,
    )
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    estimate = estimate_offset([_model_of(rng, track, frames, offset, 0.5)], track)
    assert estimate.offset_s is None
    assert estimate.reason is not None and "flat" in estimate.reason


def test_a_repeating_pattern_is_ambiguous_and_two_models_settle_it() -> None:
    """A lawnmower of four lines: the reconstruction of lines 1-2 fits lines 3-4 as well once the
    similarity has moved it (one period later), and that of lines 3-4 fits lines 1-2: each alone
    is ambiguous and says so, naming the other offset. The two models together (each its own
    similarity, one offset) fit only the true one."""
    rng = np.random.default_rng(3)
    t, xyz, frames = _lawnmower(rng, lines=4, speed=10.0, length=300.0, spacing=80.0, interval=2.0)
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    jumps = np.flatnonzero(np.diff(frames) > 3.0)  # the turns (frames on the lines only)
    cut = int(jumps[1]) + 1  # after the second line
    period = float(frames[cut] - frames[0])
    first = _model_of(rng, track, frames[:cut], 4.2, 1.0)
    second = _model_of(rng, track, frames[cut:], 4.2, 1.0)
    for model, other in ((first, 4.2 - period), (second, 4.2 + period)):
        alone = estimate_offset([model], track)
        assert alone.offset_s is None and alone.reason is not None and "ambiguous" in alone.reason
        assert alone.competing_s or alone.best_offset_s is not None
        found = {round(x) for x in (*alone.competing_s, alone.best_offset_s or 0.0)}
        assert round(other) in found or round(other) + 1 in found or round(other) - 1 in found
    both = estimate_offset([first, second], track)
    assert both.offset_s is not None and both.sigma_s is not None
    assert abs(both.offset_s - 4.2) <= 4 * both.sigma_s + FINE_STEP_S


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-30.0, 30.0))
def test_frames_pushed_onto_a_standing_vehicle_fit_worst(seed: int, offset: float) -> None:
    """The log runs ten minutes before take-off with the vehicle standing (GPS jitter of half a
    metre): an offset that puts every frame there must not fit best (a similarity could shrink
    the model onto the jitter if the misfit were measured on the track)."""
    rng = np.random.default_rng(seed)
    t, xyz, frames = _lawnmower(rng, lines=3, speed=10.0, length=300.0, spacing=60.0, interval=2.0)
    standing_t = np.arange(-630.0, -30.0, 0.2)
    standing = xyz[0] + rng.normal(scale=0.5, size=(standing_t.size, 3))
    track = TrackXYZ(time_s=np.concatenate([standing_t, t]), xyz_m=np.vstack([standing, xyz]))
    estimate = estimate_offset([_model_of(rng, track, frames, offset, 1.0)], track)
    assert estimate.best_offset_s is not None
    assert abs(estimate.best_offset_s - offset) < 2.0, estimate


def test_frames_beyond_the_track_leave_nothing_to_search() -> None:
    track = TrackXYZ(time_s=np.array([0.0, 10.0]), xyz_m=np.array([[0.0, 0, 0], [100.0, 0, 0]]))
    model = ModelPath(
        names=tuple("abcdef"),
        capture_s=np.linspace(0.0, 30.0, 6),
        centres=np.random.default_rng(0).normal(size=(6, 3)),
    )
    estimate = estimate_offset([model], track)
    assert estimate.offset_s is None and estimate.reason is not None and "longer than" in estimate.reason


def test_pairs_join_neighbours_in_time_and_in_space() -> None:
    capture = np.array([0.0, 1.0, 2.0, 3.0])
    xy = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0], [0.0, 50.0]])
    assert frame_pairs(capture, None, time_neighbours=1, space_neighbours=0) == [(0, 1), (1, 2), (2, 3)]
    with_space = frame_pairs(capture, xy, time_neighbours=1, space_neighbours=1)
    assert (0, 3) in with_space  # the frame across the "line", 50 m away


@pytest.mark.parametrize("lines", [2, 3])
def test_uncertainty_shrinks_with_noise(lines: int) -> None:
    """Less noise, smaller stated sigma (the curve's curvature against the residual scatter)."""
    rng = np.random.default_rng(11)
    t, xyz, frames = _lawnmower(rng, lines=lines, speed=10.0, length=400.0, spacing=60.0, interval=2.0)
    track = TrackXYZ(time_s=t, xyz_m=xyz)
    noisy = estimate_offset([_model_of(np.random.default_rng(1), track, frames, 1.0, 3.0)], track)
    quiet = estimate_offset([_model_of(np.random.default_rng(1), track, frames, 1.0, 0.3)], track)
    assert noisy.sigma_s is not None and quiet.sigma_s is not None
    assert quiet.sigma_s < noisy.sigma_s


def test_a_log_with_camera_events_is_matched_and_the_flag_said_unused(tmp_path: Path) -> None:
    """With camera events the offset comes from matching them (no reconstruction is run) and the
    result says that --offset-from-images was not used."""
    from acquisition.geotag import geotag_images
    from acquisition.offset_from_images import ReconstructionOptions
    from acquisition.telemetry.model import CameraEvents, FlightLog, PositionTrack

    start = 1_700_000_000.0
    capture = start + np.cumsum(np.random.default_rng(5).uniform(1.5, 3.0, size=8))
    for k, t in enumerate(capture):
        write_frame(tmp_path / "images" / f"IMG_{k:04d}.JPG", t + 7.0)  # camera 7 s ahead
    times = np.arange(start - 10, capture[-1] + 10, 0.2)
    log = FlightLog(
        path="synthetic",
        format="csv",
        events=CameraEvents(time_utc_s=capture, seq=np.arange(8, dtype=np.int64)),
        positions=PositionTrack(
            time_utc_s=times, lat_deg=42.0 + 1e-5 * (times - start), lon_deg=np.full(times.size, -93.0)
        ),
    )
    result = geotag_images(
        tmp_path / "images", log, tmp_path / "out", dry_run=True, offset_from_images=ReconstructionOptions()
    )
    assert str(result.offset_source) == "matched"
    assert result.offset_s == pytest.approx(7.0, abs=0.01)
    assert result.offset_from_images is None
    assert any("--offset-from-images not used: the log has camera events" in w for w in result.warnings)


def test_nothing_to_compare_is_said_before_any_misfit() -> None:
    """No model of MIN_MODEL_FRAMES frames, or frames spanning longer than the whole track: no
    offset is searched, and the reason says which."""
    from acquisition.offset_from_images import MIN_MODEL_FRAMES

    t = np.arange(0.0, 60.0, 0.2)
    track = TrackXYZ(time_s=t, xyz_m=np.column_stack([5.0 * t, np.zeros_like(t), np.full_like(t, 80.0)]))

    def model(times: F64) -> ModelPath:
        return ModelPath(
            names=tuple(f"f{k}" for k in range(len(times))),
            capture_s=times,
            centres=np.column_stack([times, np.zeros_like(times), np.zeros_like(times)]),
        )

    too_few = estimate_offset([model(np.arange(MIN_MODEL_FRAMES - 1, dtype=float))], track)
    assert too_few.offset_s is None and too_few.search_s is None
    assert (
        too_few.reason == f"no reconstruction of {MIN_MODEL_FRAMES} frames or more to compare with the track"
    )
    too_long = estimate_offset([model(np.linspace(0.0, 90.0, MIN_MODEL_FRAMES + 5))], track)  # 90 s > 60 s
    assert too_long.offset_s is None and too_long.best_offset_s is None and too_long.search_s is None
    assert too_long.reason is not None and "span longer than the log's track" in too_long.reason
    assert (too_long.frames_used, too_long.models) == (MIN_MODEL_FRAMES + 5, 1)
