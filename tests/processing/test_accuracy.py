"""Similarity fit and check-point accuracy on synthetic scenes with known truth.

The scene is made here, independently of the code under test: ground points, nadir cameras at a
known height, a known model-from-ground similarity, pixel observations projected with the
pinhole equations and Gaussian noise of a known sigma. The tolerances follow from that sigma:
a ray's ground error is sigma_px x GSD horizontally and (H / B) times that in depth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from processing.accuracy import (
    MAX_TRIANGULATION_PX,
    AccuracyError,
    PinholeView,
    assess_accuracy,
    intersect_rays,
    table_3_2,
)
from processing.gcp import Observation
from processing.similarity import SimilarityError, fit_horizontal_similarity, fit_similarity

FOCAL_PX = 3000.0
WIDTH_PX, HEIGHT_PX = 4000, 3000
HEIGHT_M = 75.6  # the textbook block's mean flying height


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _nadir_cam_from_world(centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Camera x east, y south (image down), z down.
    r = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
    return r, -r @ centre


def _scene(sigma_px: float, seed: int, relief_m: float = 3.0) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    names = [f"p{k}" for k in range(12)]
    ground = {
        n: np.array([rng.uniform(0, 80), rng.uniform(0, 60), rng.uniform(-relief_m, relief_m)]) for n in names
    }
    # Model frame = s R ground + t (what an SfM model is: arbitrary scale, rotation, origin).
    s, rot, t = 0.037, _rotation(rng), np.array([5.0, -2.0, 11.0])
    views: dict[str, PinholeView] = {}
    centres = [np.array([x, y, HEIGHT_M]) for x in (0.0, 25.0, 50.0, 75.0) for y in (0.0, 30.0, 60.0)]
    for k, c in enumerate(centres):
        rg, tg = _nadir_cam_from_world(c)
        views[f"img{k}.jpg"] = PinholeView(
            focal_px=FOCAL_PX,
            principal_xy_px=(WIDTH_PX / 2, HEIGHT_PX / 2),
            cam_from_world_rotation=rg @ rot.T,
            cam_from_world_translation=s * tg - rg @ rot.T @ t,
        )
    obs = []
    for n, xyz in ground.items():
        for k, c in enumerate(centres):
            rg, tg = _nadir_cam_from_world(c)
            cam = rg @ xyz + tg
            px = np.array(
                [FOCAL_PX * cam[0] / cam[2] + WIDTH_PX / 2, FOCAL_PX * cam[1] / cam[2] + HEIGHT_PX / 2]
            )
            if 0 <= px[0] < WIDTH_PX and 0 <= px[1] < HEIGHT_PX:
                px = px + rng.normal(scale=sigma_px, size=2) if sigma_px > 0 else px
                obs.append(Observation(point=n, image=f"img{k}.jpg", x_px=float(px[0]), y_px=float(px[1])))
    return {"ground": ground, "views": views, "obs": obs, "s": s, "rot": rot, "t": t, "names": names}


def test_noise_free_scene_is_placed_exactly() -> None:
    sc = _scene(0.0, seed=1)
    names = sc["names"]
    result = assess_accuracy(
        ground_xyz_m=sc["ground"],
        observations=sc["obs"],
        views=sc["views"],
        control=names[:6],
        check=names[6:],
    )
    # The fitted ground-from-model similarity is the inverse of the scene's model-from-ground.
    assert result.similarity.scale == pytest.approx(1 / sc["s"], rel=1e-9)
    assert np.allclose(result.similarity.rotation, sc["rot"].T, atol=1e-9)
    assert result.check is not None
    assert result.check.rmse_total_m < 1e-6
    assert result.check.rmse_image_px < 1e-6
    assert result.check.rmse_marks_px < 1e-6
    assert result.control.range_m == pytest.approx(HEIGHT_M - np.mean([v[2] for v in sc["ground"].values()]))


def test_known_survey_errors_at_check_points_come_out_per_axis_and_in_total() -> None:
    # Heights known; the check points' surveyed coordinates are off by known amounts (a survey
    # error), the control exact and the marks noise-free: the fit is exact, and each check point's
    # residual is its offset. The RMSE rows are then the offsets' RMSE, axis by axis, horizontal
    # and 3-D (the total takes dz squared, as dx and dy: sqrt(mean(dx^2 + dy^2 + dz^2))).
    sc = _scene(0.0, seed=3)
    names = sc["names"]
    rng = np.random.default_rng(5)
    offsets = {n: rng.uniform([-0.4, -0.4, 0.5], [0.4, 0.4, 2.0]) for n in names[6:]}
    ground = {n: v + offsets[n] if n in offsets else v for n, v in sc["ground"].items()}
    result = assess_accuracy(
        ground_xyz_m=ground, observations=sc["obs"], views=sc["views"], control=names[:6], check=names[6:]
    )
    assert result.heights_known and result.check is not None
    off = np.array([offsets[r.name] for r in result.residuals if r.role == "check"])
    assert len(off) == 6
    rx, ry, rz = np.sqrt(np.mean(off**2, axis=0))
    assert result.check.rmse_x_m == pytest.approx(rx, abs=1e-6)
    assert result.check.rmse_y_m == pytest.approx(ry, abs=1e-6)
    assert result.check.rmse_z_m == pytest.approx(rz, abs=1e-6) and rz > 0.5
    assert result.check.rmse_horizontal_m == pytest.approx(
        math.sqrt(np.mean(off[:, 0] ** 2 + off[:, 1] ** 2)), abs=1e-6
    )
    assert result.check.rmse_total_m == pytest.approx(math.sqrt(np.mean(np.sum(off**2, axis=1))), abs=1e-6)
    assert result.control.rmse_total_m < 1e-6
    row = next(line for line in table_3_2(result).splitlines() if line.startswith("check"))
    assert f"{result.check.rmse_total_m:.3f}" in row.split()


@pytest.mark.parametrize("sigma_px", [0.3, 1.0, 3.0])
def test_check_point_rmse_follows_the_injected_noise(sigma_px: float) -> None:
    # Many independent scenes so the RMSE is a stable estimate.
    gsd_m = HEIGHT_M / FOCAL_PX
    rows = []
    image_px = []
    marks_px = []
    for seed in range(12):
        sc = _scene(sigma_px, seed=100 + seed)
        names = sc["names"]
        r = assess_accuracy(
            ground_xyz_m=sc["ground"],
            observations=sc["obs"],
            views=sc["views"],
            control=names[:6],
            check=names[6:],
        )
        assert r.check is not None
        rows.append(r.check)
        image_px.append(r.check.rmse_image_px)
        marks_px.append(r.check.rmse_marks_px)
    horizontal = math.sqrt(np.mean([row.rmse_horizontal_m**2 for row in rows]))
    vertical = math.sqrt(np.mean([row.rmse_z_m**2 for row in rows]))
    # Per axis a ray misses by sigma x GSD; several rays average it down, the similarity fit on
    # noisy control adds to it: the horizontal RMSE stays within [0.1, 2] x sigma x GSD x sqrt(2).
    per_ray_m = sigma_px * gsd_m * math.sqrt(2)
    assert 0.1 * per_ray_m < horizontal < 2.0 * per_ray_m
    # Depth: H / B times worse; the shortest base here is 25 m -> at most ~3x horizontal per ray.
    assert 0.1 * per_ray_m < vertical < 2.0 * (HEIGHT_M / 25.0) * per_ray_m
    # Image residuals: the 2D noise, sigma x sqrt(2), plus a little from the fit.
    assert 0.8 * sigma_px * math.sqrt(2) < np.mean(image_px) < 1.5 * sigma_px * math.sqrt(2)
    # The marks against their own intersection: the noise less the three coordinates fitted to it.
    assert 0.3 * sigma_px * math.sqrt(2) < np.mean(marks_px) < np.mean(image_px)


def test_fewer_than_three_triangulable_control_points_is_refused() -> None:
    sc = _scene(0.5, seed=3)
    names = sc["names"]
    obs = [o for o in sc["obs"] if not (o.point in names[2:6] and o.image != "img0.jpg")]
    with pytest.raises(AccuracyError, match="only 2 control point"):
        assess_accuracy(
            ground_xyz_m=sc["ground"], observations=obs, views=sc["views"], control=names[:6], check=names[6:]
        )


def test_a_point_in_one_registered_frame_is_listed_not_used() -> None:
    sc = _scene(0.5, seed=4)
    names = sc["names"]
    first = next(o for o in sc["obs"] if o.point == names[7])
    obs = [o for o in sc["obs"] if o.point != names[7]] + [first]
    r = assess_accuracy(
        ground_xyz_m=sc["ground"], observations=obs, views=sc["views"], control=names[:6], check=names[6:]
    )
    assert [t.name for t in r.unused] == [names[7]]
    assert r.check is not None and r.check.n_points == 5
    assert "1:" in table_3_2(r)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.floats(1e-3, 1e3),
    n=st.integers(3, 30),
)
def test_similarity_recovers_any_transform(seed: int, scale: float, n: int) -> None:
    rng = np.random.default_rng(seed)
    src = rng.normal(scale=50.0, size=(n, 3))
    rot = _rotation(rng)
    t = rng.normal(scale=1000.0, size=3)
    dst = scale * src @ rot.T + t
    sim = fit_similarity(src, dst)
    assert sim.scale == pytest.approx(scale, rel=1e-7)
    assert np.allclose(sim.rotation, rot, atol=1e-7)
    assert np.allclose(sim.apply(src), dst, atol=1e-6 * max(1.0, scale) * 50)
    assert np.allclose(sim.inverse().apply(dst), src, atol=1e-6 * 50)


def test_similarity_refuses_collinear_points() -> None:
    src = np.array([[0.0, 0, 0], [1, 1, 1], [2, 2, 2], [5, 5, 5]])
    with pytest.raises(SimilarityError, match="on a line"):
        fit_similarity(src, src * 2)


def test_rays_meet_at_the_point() -> None:
    rng = np.random.default_rng(0)
    p = rng.normal(size=3)
    origins = rng.normal(scale=10, size=(5, 3))
    d = p - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.allclose(intersect_rays(origins, d), p, atol=1e-9)


def _zero_heights(ground: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The survey as a gcp_list.txt with unknown heights gives it: east, north, 0.0."""
    return {n: np.array([v[0], v[1], 0.0]) for n, v in ground.items()}


def _horizontal_rmse(result: object, truth: dict[str, np.ndarray], names: list[str]) -> float:
    placed = result.placed_xyz_m  # type: ignore[attr-defined]
    return math.sqrt(np.mean([np.sum((placed[n][:2] - truth[n][:2]) ** 2) for n in names]))


@pytest.mark.parametrize("sigma_px", [0.0, 1.0])
def test_unknown_heights_over_relief_horizontal_fit_within_noise_seven_parameter_biased(
    sigma_px: float,
) -> None:
    # A hilly site (points +-15 m about a mean) surveyed in plan only: gcp_list.txt says 0.0 for
    # every height. The horizontal fit places the check points within the noise; the 7-parameter
    # fit to the 0.0 heights flattens the relief: its scale shrinks by about var(z) / var(x, y, z).
    gsd_m = HEIGHT_M / FOCAL_PX
    per_ray_m = max(sigma_px, 1e-6) * gsd_m * math.sqrt(2)
    for seed in range(4):
        sc = _scene(sigma_px, seed=300 + seed, relief_m=15.0)
        names, truth = sc["names"], sc["ground"]
        flat = _zero_heights(truth)
        common = {"ground_xyz_m": flat, "observations": sc["obs"], "views": sc["views"]}
        horizontal = assess_accuracy(**common, control=names[:6], check=names[6:])
        seven = assess_accuracy(**common, control=names[:6], check=names[6:], heights_known=True)
        assert not horizontal.heights_known and horizontal.check is not None
        assert horizontal.check.rmse_z_m is None and horizontal.check.rmse_total_m is None
        assert "tilt fitted" in horizontal.fit
        assert _horizontal_rmse(horizontal, truth, names[6:]) < 2.0 * per_ray_m
        assert horizontal.similarity.scale == pytest.approx(1 / sc["s"], rel=max(1e-9, 2e-3 * sigma_px))
        # The seven-parameter fit: tens of centimetres to metres off, its scale short by the relief.
        assert _horizontal_rmse(seven, truth, names[6:]) > 5.0 * per_ray_m + 0.2
        xyz = np.array([truth[n] for n in names[:6]])
        shrink = np.var(xyz[:, 2]) / np.sum(np.var(xyz, axis=0))
        assert seven.similarity.scale * sc["s"] < 1.0 - 0.3 * shrink
        assert "Z: not measurable" in table_3_2(horizontal)


def test_unknown_heights_on_level_ground_keep_the_model_level() -> None:
    # Targets on level ground (1 cm of relief): their plan positions cannot fix a tilt, so the
    # model is levelled on them and the check points come back within the noise.
    sigma_px = 1.0
    per_ray_m = sigma_px * HEIGHT_M / FOCAL_PX * math.sqrt(2)
    sc = _scene(sigma_px, seed=41, relief_m=0.01)
    names = sc["names"]
    r = assess_accuracy(
        ground_xyz_m=_zero_heights(sc["ground"]),
        observations=sc["obs"],
        views=sc["views"],
        control=names[:6],
        check=names[6:],
    )
    assert "levelled" in r.fit
    assert _horizontal_rmse(r, sc["ground"], names[6:]) < 2.0 * per_ray_m
    # Placed heights are relative to the control points' mean, which is the 0.0 datum.
    assert abs(np.mean([r.placed_xyz_m[n][2] for n in names[:6]])) < 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-2, 1e2), n=st.integers(4, 20))
def test_horizontal_fit_recovers_any_similarity_from_plan_positions(seed: int, scale: float, n: int) -> None:
    rng = np.random.default_rng(seed)
    ground = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-10, 10, n)])
    rot = _rotation(rng)
    model = (ground @ rot) / scale + rng.normal(scale=100.0, size=3)  # ground = scale R model + t
    up = rot.T @ np.array([0.0, 0.0, 1.0])
    fit = fit_horizontal_similarity(model, ground[:, :2], up_hint=up)
    placed = fit.similarity.apply(model)
    assert np.allclose(placed[:, :2], ground[:, :2], atol=1e-6 * 50)
    # Heights come back up to the datum shift (their mean goes to 0.0).
    assert np.allclose(placed[:, 2] - placed[:, 2].mean(), ground[:, 2] - ground[:, 2].mean(), atol=1e-6 * 50)
    assert fit.similarity.scale == pytest.approx(scale, rel=1e-7)


def test_a_mis_marked_observation_is_dropped_and_named() -> None:
    # One mark of a point seen in three frames or more is moved 300 px (a wrong target): it is
    # left out with a warning naming the point and the image, and the point is still used.
    sc = _scene(0.5, seed=7)
    names = sc["names"]
    counts = {n: sum(o.point == n for o in sc["obs"]) for n in names}
    victim = next(n for n in names[:6] if counts[n] >= 3)
    bad = next(o for o in sc["obs"] if o.point == victim)
    obs = [
        Observation(point=o.point, image=o.image, x_px=o.x_px + 300.0, y_px=o.y_px) if o is bad else o
        for o in sc["obs"]
    ]
    r = assess_accuracy(
        ground_xyz_m=sc["ground"], observations=obs, views=sc["views"], control=names[:6], check=names[6:]
    )
    assert [(d.point, d.image) for d in r.dropped_marks] == [(victim, bad.image)]
    assert r.dropped_marks[0].residual_px > MAX_TRIANGULATION_PX
    assert any(victim in w and bad.image in w for w in r.warnings)
    assert victim not in {t.name for t in r.unused}
    point = next(p for p in r.residuals if p.name == victim)
    assert point.n_images == counts[victim] - 1
    assert math.hypot(point.dx_m, point.dy_m) < 0.05  # 0.5 px marks, 2.5 cm pixels


def test_two_marks_that_disagree_leave_the_point_out() -> None:
    # With two marks there is no majority: the point is listed with the reason, not guessed.
    sc = _scene(0.0, seed=8)
    names = sc["names"]
    victim = names[6]
    mine = [o for o in sc["obs"] if o.point == victim][:2]
    # Moved across the baseline (along it, two rays still meet: only depth changes).
    base = sc["rot"].T @ (sc["views"][mine[1].image].centre - sc["views"][mine[0].image].centre)  # ground
    across = np.array([-base[1], base[0]]) / math.hypot(base[0], base[1])
    shift = 200.0 * np.array([across[0], -across[1]])  # image y points south
    obs = [o for o in sc["obs"] if o.point != victim] + [
        mine[0],
        Observation(
            point=victim, image=mine[1].image, x_px=mine[1].x_px + shift[0], y_px=mine[1].y_px + shift[1]
        ),
    ]
    r = assess_accuracy(
        ground_xyz_m=sc["ground"], observations=obs, views=sc["views"], control=names[:6], check=names[6:]
    )
    assert victim in {t.name for t in r.unused}
    assert not r.dropped_marks


def test_control_far_off_their_survey_is_flagged_and_good_control_is_not() -> None:
    sc = _scene(0.5, seed=9)
    names = sc["names"]
    common = {"observations": sc["obs"], "views": sc["views"], "control": names[:6], "check": names[6:]}
    good = assess_accuracy(ground_xyz_m=sc["ground"], **common)
    # A pixel on the ground: height above the points over the focal length (nadir frames).
    mean_z = np.mean([sc["ground"][n][2] for n in names[:6]])
    assert good.ground_pixel_m == pytest.approx((HEIGHT_M - mean_z) / FOCAL_PX, rel=0.1)
    assert not good.warnings
    rng = np.random.default_rng(0)
    gps = {n: v + np.array([*rng.normal(scale=1.5, size=2), 0.0]) for n, v in sc["ground"].items()}
    r = assess_accuracy(ground_xyz_m=gps, **common)
    assert any("marking errors do not explain it" in w for w in r.warnings)


@pytest.mark.parametrize("heights", ["known", "unknown"])
def test_a_control_point_off_its_survey_stands_out_when_left_out(heights: str) -> None:
    # One control point surveyed 1 m off (a blunder): fitted without it, it misses by 1 m, the
    # largest left-out miss of all.
    sc = _scene(0.5, seed=12)
    names = sc["names"]
    ground = sc["ground"] if heights == "known" else _zero_heights(sc["ground"])
    bad = names[2]
    ground = {n: v + (np.array([0.6, -0.8, 0.0]) if n == bad else 0.0) for n, v in ground.items()}
    r = assess_accuracy(
        ground_xyz_m=ground, observations=sc["obs"], views=sc["views"], control=names[:7], check=names[7:]
    )
    left_out = {p.name: p.left_out_horizontal_m for p in r.residuals if p.role == "control"}
    assert left_out[bad] == pytest.approx(1.0, abs=0.15)
    # The others carry the blunder in their own fits (most near it), but it stands out.
    assert all(v is not None and v < 0.75 * left_out[bad] for n, v in left_out.items() if n != bad)
    assert all(p.left_out_horizontal_m is None for p in r.residuals if p.role == "check")
