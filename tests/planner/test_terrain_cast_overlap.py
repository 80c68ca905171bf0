"""Overlap over relief, against an independent ray cast: each planned frame's rays (its corners and
points along its edges) cast here onto the DEM from the station's position and altitude, the
footprints made shapely polygons and neighbouring frames intersected. No planner code computes
the oracle: positions come from the plan's stations (lon, lat, altitude above home), the DEM is
read with rasterio and interpolated here, the pairs and their spacing are found from the stations.

The overlap of a pair is the area both footprints cover over the larger of their areas, within
the stretch the pair answers for (forward: the band of the line, a line spacing wide; side: the
first frame's trigger step along the line); over flat ground it is Eq. 3-5's 1 - B / D. The
planner judges the narrowest place of each pair, so its minimum may be below this one, never
above; and where it says the overlaps hold, they hold here.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import rasterio
import shapely
from pyproj import Geod, Transformer
from rasterio.transform import from_origin

from planner.errors import PlanningError
from planner.plan import SurveyPlan
from planner.spec import load_spec
from planner.survey import plan_survey

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
UTM = "EPSG:32630"
GEOD = Geod(ellps="WGS84")
#: Rays along each image edge, corners included.
EDGE_RAYS = 17


class Raster:
    """A DEM as read by rasterio, bilinear between cell centres."""

    def __init__(self, path: Path) -> None:
        with rasterio.open(path) as d:
            assert str(d.crs) == UTM
            self.z = d.read(1).astype(float)
            t = d.transform
            self.left, self.top, self.res = t.c, t.f, t.a

    def at(self, e: np.ndarray, n: np.ndarray) -> np.ndarray:
        col = (e - self.left) / self.res - 0.5
        row = (self.top - n) / self.res - 0.5
        c0 = np.clip(np.floor(col).astype(int), 0, self.z.shape[1] - 2)
        r0 = np.clip(np.floor(row).astype(int), 0, self.z.shape[0] - 2)
        fc, fr = np.clip(col - c0, 0, 1), np.clip(row - r0, 0, 1)
        z = self.z
        top = z[r0, c0] * (1 - fc) + z[r0, c0 + 1] * fc
        bottom = z[r0 + 1, c0] * (1 - fc) + z[r0 + 1, c0 + 1] * fc
        return np.asarray(top * (1 - fr) + bottom * fr, float)


def cast_footprints(plan: SurveyPlan, dem: Raster) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 4 (EDGE_RAYS - 1), 2) footprint rings in UTM, the stations in UTM and their heading
    (grid unit vectors)."""
    st = plan.stations
    to_utm = Transformer.from_crs("EPSG:4326", UTM, always_xy=True)
    e, n = to_utm.transform(st.lon_deg, st.lat_deg)
    e, n = np.asarray(e), np.asarray(n)
    lon2, lat2, _ = GEOD.fwd(st.lon_deg, st.lat_deg, st.heading_deg, np.full(len(st), 10.0))
    e2, n2 = to_utm.transform(lon2, lat2)
    h = np.stack([np.asarray(e2) - e, np.asarray(n2) - n], axis=1)
    h /= np.linalg.norm(h, axis=1)[:, None]
    right = np.stack([h[:, 1], -h[:, 0]], axis=1)
    cam = plan.camera
    f = cam.focal_length_mm
    # landscape: the image's width across the line, its height along it
    half_across, half_along = cam.sensor_width_mm / 2.0, cam.sensor_height_mm / 2.0
    s = np.linspace(-1.0, 1.0, EDGE_RAYS)
    ring = np.concatenate(
        [
            np.stack([s[:-1], np.ones(EDGE_RAYS - 1)], 1),
            np.stack([np.ones(EDGE_RAYS - 1), -s[:-1]], 1),
            np.stack([-s[:-1], -np.ones(EDGE_RAYS - 1)], 1),
            np.stack([-np.ones(EDGE_RAYS - 1), s[:-1]], 1),
        ]
    )  # (R, 2): across, along in units of the half sensor
    z0 = st.alt_rel_home_m + plan.home.alt_amsl_m
    out = np.zeros((len(st), len(ring), 2))
    for k in range(len(st)):
        d_xy = (ring[:, :1] * half_across * right[k] + ring[:, 1:] * half_along * h[k]) / f  # per mm down
        # march down the rays (1 m of height at a time), then bisect
        t_hi = np.full(len(ring), np.nan)
        for depth in np.arange(1.0, 600.0, 1.0):
            x = e[k] + d_xy[:, 0] * depth
            y = n[k] + d_xy[:, 1] * depth
            below = (z0[k] - depth <= dem.at(x, y)) & np.isnan(t_hi)
            t_hi[below] = depth
            if not np.isnan(t_hi).any():
                break
        lo, hi = t_hi - 1.0, t_hi
        for _ in range(30):
            mid = (lo + hi) / 2
            above = z0[k] - mid > dem.at(e[k] + d_xy[:, 0] * mid, n[k] + d_xy[:, 1] * mid)
            lo = np.where(above, mid, lo)
            hi = np.where(above, hi, mid)
        out[k, :, 0] = e[k] + d_xy[:, 0] * hi
        out[k, :, 1] = n[k] + d_xy[:, 1] * hi
    return out, np.stack([e, n], 1), h


def independent_overlaps(plan: SurveyPlan, dem: Raster) -> tuple[float, float]:
    """The smallest forward and side overlap (percent) of neighbouring nadir frames (module
    docstring)."""
    rings, xy, h = cast_footprints(plan, dem)
    st = plan.stations
    polys = shapely.polygons(rings)
    along_axis = h[0]
    across_axis = np.array([along_axis[1], -along_axis[0]])
    u, v = xy @ along_axis, xy @ across_axis
    lines = sorted(set(st.line_index.tolist()), key=lambda r: float(np.mean(v[st.line_index == r])))
    steps = []
    for r in lines:
        k = np.flatnonzero(st.line_index == r)
        steps.extend(np.diff(np.sort(u[k])).tolist())
    base = float(np.median(steps))
    gaps = np.diff([float(np.mean(v[st.line_index == r])) for r in lines])
    spacing = float(np.median(gaps))

    def share(a: int, b: int, band: shapely.Geometry) -> float:
        pa, pb = shapely.intersection(polys[a], band), shapely.intersection(polys[b], band)
        return float(shapely.area(shapely.intersection(pa, pb)) / max(pa.area, pb.area))

    def strip(centre: float, half: float, axis: np.ndarray, other: np.ndarray, at: int) -> shapely.Geometry:
        far = 1e3
        c = centre * axis + float(xy[at] @ other) * other
        corners = [c + s * half * axis + t * far * other for s, t in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        return shapely.Polygon(corners)

    front = []
    for r in lines:
        k = np.flatnonzero(st.line_index == r)
        k = k[np.argsort(u[k])]
        for a, b in itertools.pairwise(k):
            if u[b] - u[a] < 1.5 * base:
                front.append(
                    share(int(a), int(b), strip(float(v[a]), spacing / 2, across_axis, along_axis, int(a)))
                )
    side = []
    for r0, r1 in itertools.pairwise(lines):
        k0, k1 = np.flatnonzero(st.line_index == r0), np.flatnonzero(st.line_index == r1)
        if abs(float(np.mean(v[k1]) - np.mean(v[k0]))) > 1.5 * spacing:
            continue
        for a in k0:
            b = k1[np.argmin(np.abs(u[k1] - u[a]))]
            if abs(u[b] - u[a]) <= base:
                side.append(
                    share(int(a), int(b), strip(float(u[a]), base / 2, along_axis, across_axis, int(a)))
                )
    return 100.0 * min(front), 100.0 * min(side)


def _block(tmp_path: Path, name: str, z_of: object, *, follow: bool, accept: bool = False) -> Path:
    """A 360 x 300 m block near 42.2 N with lines north-south, its DEM (1 m cells, UTM 30N) from
    ``z_of(easting offset, northing offset)``."""
    to_utm = Transformer.from_crs("EPSG:4326", UTM, always_xy=True)
    e0, n0 = to_utm.transform(-1.45, 42.2)
    e0, n0 = math.floor(e0 / 60.0) * 60.0, math.floor(n0)
    cells = 1100
    west, north = e0 - 400.0, n0 + 700.0
    de = west + 0.5 + np.arange(cells) - e0
    dn = north - 0.5 - np.arange(cells) - n0
    ge, gn = np.meshgrid(de, dn)
    z = np.asarray(z_of(ge, gn), dtype="float32")  # type: ignore[operator]
    tif = tmp_path / f"{name}.tif"
    with rasterio.open(
        tif, "w", driver="GTiff", height=cells, width=cells, count=1, dtype="float32",
        crs=UTM, transform=from_origin(west, north, 1.0, 1.0),
    ) as d:  # fmt: skip
        d.write(z, 1)
    to_ll = Transformer.from_crs(UTM, "EPSG:4326", always_xy=True)
    corners = [
        to_ll.transform(e0 + dx, n0 + dy) for dx, dy in ((0, 0), (360, 0), (360, 300), (0, 300), (0, 0))
    ]
    (tmp_path / f"{name}.geojson").write_text(
        '{"type": "Polygon", "coordinates": [' + str([list(c) for c in corners]) + "]}"
    )
    home_lon, home_lat = to_ll.transform(e0 - 60.0, n0 - 20.0)
    home_z = float(np.asarray(z_of(np.array([-60.0]), np.array([-20.0])))[0])  # type: ignore[operator]
    spec = tmp_path / f"{name}.toml"
    spec.write_text(
        f'name = "{name}"\narea = "{name}.geojson"\n[camera]\nmodel = "canon-eos-350d-20mm"\n'
        f'orientation = "landscape"\n'
        f"[survey]\ngsd_cm = 2.4\nfront_overlap_pct = 80\nside_overlap_pct = 70\nspeed_m_s = 4\n"
        f"direction_deg = 0\nturnaround_m = 10\n"
        f'[terrain]\ndem = "{name}.tif"\nfollow = {str(follow).lower()}\ntolerance_m = 2\n'
        f"accept_overlap_loss = {str(accept).lower()}\n"
        f"[vehicle]\nhome = [{home_lat}, {home_lon}]\nhome_alt_amsl_m = {home_z}\nmax_alt_agl_m = 150\n"
        f"max_flight_time_min = 90\n"
    )
    return spec


def ridges_along(de: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """12 m ridges every 60 m, parallel to the lines."""
    return 400.0 + 6.0 * (1.0 - np.cos(2.0 * np.pi * de / 60.0)) + 0.0 * dn


def ridges_across(de: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """14 m ridges every 50 m, across the lines."""
    return 400.0 + 7.0 * (1.0 - np.cos(2.0 * np.pi * dn / 50.0)) + 0.0 * de


def steps(de: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """Terraces: 9 m steps every 45 m east (up twice, then down) and a 6 m step every 70 m north."""
    return 400.0 + 9.0 * (np.floor(de / 45.0) % 3) + 6.0 * (np.floor(dn / 70.0) % 2)


@pytest.mark.parametrize("ground", [ridges_along, ridges_across, steps], ids=lambda g: g.__name__)
@pytest.mark.parametrize("follow", [True, False], ids=["following", "constant"])
def test_overlaps_hold_over_relief_by_an_independent_cast(
    tmp_path: Path, ground: object, follow: bool
) -> None:
    spec = _block(tmp_path, "relief", ground, follow=follow)
    try:
        plan = plan_survey(load_spec(spec))
    except PlanningError as error:  # it may refuse, but then it says where and by how much
        message = str(error)
        assert "accept_overlap_loss" in message and "lon " in message and "points below" in message
        plan = plan_survey(load_spec(_block(tmp_path, "relief", ground, follow=follow, accept=True)))
        terrain = plan.summary.terrain
        assert terrain is not None
        front, side = independent_overlaps(plan, Raster(tmp_path / "relief.tif"))
        assert float(terrain["side_overlap_min_pct"]) <= side + 1.0  # type: ignore[arg-type]
        assert float(terrain["front_overlap_min_pct"]) <= front + 1.0  # type: ignore[arg-type]
        return
    terrain = plan.summary.terrain
    assert terrain is not None
    front, side = independent_overlaps(plan, Raster(tmp_path / "relief.tif"))
    assert front >= 80.0 - 1.0, f"forward overlap on the ground {front:.1f} %"
    assert side >= 70.0 - 1.0, f"side overlap on the ground {side:.1f} %"
    # what the plan reports is never more than what the frames give
    assert float(terrain["front_overlap_min_pct"]) <= front + 1.0  # type: ignore[arg-type]
    assert float(terrain["side_overlap_min_pct"]) <= side + 1.0  # type: ignore[arg-type]


def test_overlaps_hold_over_the_gully_by_an_independent_cast() -> None:
    plan = plan_survey(load_spec(MISSIONS / "bardenas-gully-terrain.toml"))
    terrain = plan.summary.terrain
    assert terrain is not None
    front, side = independent_overlaps(plan, Raster(MISSIONS / "bardenas-gully-dem.tif"))
    assert front >= 80.0 - 1.0 and side >= 70.0 - 1.0, (front, side)
    assert float(terrain["front_overlap_min_pct"]) <= front + 1.0  # type: ignore[arg-type]
    assert float(terrain["side_overlap_min_pct"]) <= side + 1.0  # type: ignore[arg-type]
