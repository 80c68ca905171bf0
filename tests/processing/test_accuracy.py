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

from processing.accuracy import AccuracyError, PinholeView, assess_accuracy, intersect_rays, table_3_2
from processing.gcp import Observation
from processing.similarity import SimilarityError, fit_similarity

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


def _scene(sigma_px: float, seed: int) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    names = [f"p{k}" for k in range(12)]
    ground = {n: np.array([rng.uniform(0, 80), rng.uniform(0, 60), rng.uniform(-3, 3)]) for n in names}
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
