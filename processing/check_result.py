"""What a coverage check found (:class:`CheckResult`, report.json's twin) and its parts:
:class:`Gap`, :class:`FrameFlag`, the stereo classes of the cells."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from planner.geo import LocalFrame

from .check_scale import Blame, ScaleFinding
from .check_stereo import FrameFlag, StereoFigures
from .distribution import Distribution
from .frames import Frames
from .pixel_match import PixelFigures
from .plan_frames import PlanInfo
from .verdict import Thresholds


@dataclass(frozen=True, kw_only=True)
class Gap:
    """A connected part of the area seen by no frame.

    ``polygon_xy`` in the check's local frame (metres), ``polygon_lonlat`` in WGS84;
    ``area_m2`` measured in the local frame.
    """

    index: int
    area_m2: float
    centroid_lon_deg: float
    centroid_lat_deg: float
    polygon_xy: Polygon
    polygon_lonlat: Polygon


@dataclass(frozen=True, kw_only=True)
class CheckResult:
    """Everything a check measured, and the verdict. ``as_dict`` is report.json.

    Rasters share ``grid`` (rows from north, ``extent_xy_m`` = (west, south, east, north) in
    ``frame``'s metres): ``view_count`` (views per cell), ``in_area`` (cell centre inside the
    area), ``gsd_cm_raster`` (finest GSD that sees each cell, NaN where none does),
    ``stereo.stereo_class`` (:class:`~processing.check_stereo.StereoFigures`).
    Per-frame arrays follow ``frames``' rows; ``stereo``: pairs, overlaps, B/H, convergence,
    speed and blur (:func:`processing.check_stereo.measure_stereo`).
    """

    passed: bool
    reasons: tuple[str, ...]
    warnings: tuple[str, ...]
    notes: tuple[str, ...]
    thresholds: Thresholds
    frames: Frames
    frame: LocalFrame
    ground_description: str
    area_source: str
    area_xy: Polygon | MultiPolygon
    area_lonlat: Polygon | MultiPolygon
    area_m2: float
    cell_m: float
    grid: Any
    extent_xy_m: tuple[float, float, float, float]
    view_count: NDArray[np.int32]
    in_area: NDArray[np.bool_]
    seen_pct: dict[int, float]
    gaps: tuple[Gap, ...]
    footprints_xy: NDArray[np.float64]
    footprints_lonlat: NDArray[np.float64]
    centres_xy: NDArray[np.float64]
    height_agl_m: NDArray[np.float64]
    gsd_cm: NDArray[np.float64]
    gsd_cm_raster: NDArray[np.float64] | None
    stereo: StereoFigures
    flagged: tuple[FrameFlag, ...]
    plan: PlanInfo | None = None
    unpositioned: tuple[str, ...] = ()
    left_out: tuple[tuple[str, str], ...] = ()
    camera_source: str = ""
    pixels: PixelFigures | None = None
    #: The measured image scale against the tags' (:mod:`processing.check_scale`); when ``used``,
    #: the footprints, coverage and GSD (and for the heights, heights and B/H) come from it.
    scale: ScaleFinding | None = None
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def base_height_along_line(self) -> Distribution | None:
        """B/H of consecutive frames of a line (the forward-overlap pairs)."""
        return Distribution.of(self.stereo.pair_base_height_ratio[self.stereo.pair_along_line])

    @property
    def base_height_across_lines(self) -> Distribution | None:
        """B/H of pairs of frames on different lines (the side-overlap pairs)."""
        return Distribution.of(self.stereo.pair_base_height_ratio[self.stereo.pair_across_lines])

    @property
    def gap_area_m2(self) -> float:
        return float(sum(g.area_m2 for g in self.gaps))

    def output_crs(self) -> tuple[str, Any]:
        """The one projected CRS of the check's outputs: the UTM zone that holds the area (its EPSG
        code, as coverage.tif), else the check's own transverse Mercator frame; (name, pyproj CRS).
        GeoJSON files are WGS84 longitude/latitude by their standard (RFC 7946)."""
        from pyproj import CRS

        from .geotiff import utm_epsg

        epsg = utm_epsg(*self.area_lonlat.bounds)
        if epsg is not None:
            crs = CRS.from_epsg(epsg)
            return f"EPSG:{epsg} ({crs.name})", crs
        return f"{self.frame.crs.to_string()} (the check's transverse Mercator frame)", self.frame.crs

    def extent_in_output_crs(self) -> tuple[float, float, float, float]:
        """The grid's extent (west, south, east, north) in :meth:`output_crs`, metres."""
        from pyproj import Transformer

        _, crs = self.output_crs()
        to_out = Transformer.from_crs(self.frame.crs, crs, always_xy=True)
        west, south, east, north = self.extent_xy_m
        xs, ys = to_out.transform([west, east, east, west], [south, south, north, north])
        return (float(min(xs)), float(min(ys)), float(max(xs)), float(max(ys)))

    def key_figures(self) -> list[tuple[str, str]]:
        """The figures a person reads first, as (label, text) rows."""
        rows: list[tuple[str, str]] = [
            (
                "frames",
                f"{len(self.frames)} ({self.frames.camera.id}, attitude {self.frames.attitude_source.value})",
            ),
            *([("camera", self.camera_source)] if self.camera_source else []),
            ("ground", self.ground_description),
            ("area", f"{self.area_m2 / 1e4:.2f} ha ({self.area_source}), cells {self.cell_m:g} m"),
            ("CRS", f"{self.output_crs()[0]} (coverage.tif, report.json); GeoJSON in WGS84"),
            (
                "seen by >= 1 / 3 / 5 frames",
                " / ".join(f"{self.seen_pct[k]:.1f} %" for k in (1, 3, 5)),
            ),
            ("gaps", f"{len(self.gaps)}, {self.gap_area_m2:.0f} m2" if self.gaps else "none"),
        ]
        plan = self.plan
        for label, dist, planned in (
            (
                "forward overlap",
                self.stereo.forward_overlap_pct,
                plan.planned.summary.front_overlap_pct if plan else None,
            ),
            (
                "side overlap",
                self.stereo.side_overlap_pct,
                plan.planned.summary.side_overlap_pct if plan else None,
            ),
        ):
            if dist is None:
                rows.append((label, "not measured (no consecutive frames along a line)"))
                continue
            text = f"median {dist.median:.0f} % (10-90 %: {dist.p10:.0f}-{dist.p90:.0f} %)"
            if planned is not None:
                text += f", planned {planned:g} %"
            rows.append((label, text))
        for label, dist in (
            ("B/H along lines", self.base_height_along_line),
            ("B/H across lines", self.base_height_across_lines),
        ):
            if dist is None:
                rows.append((label, "no such pair"))
            else:
                text = f"median {dist.median:.2f} (10-90 %: {dist.p10:.2f}-{dist.p90:.2f})"
                rows.append((label, f"{text} over {dist.count} pairs"))
        if self.stereo.good_pair_pct is not None:
            rows.append(
                (
                    "stereo",
                    f"{self.stereo.good_pair_pct:.1f} % of the area has a pair "
                    f"({self.stereo.good_pair_basis}) with B/H in "
                    f"{self.thresholds.min_base_height_ratio:g}-{self.thresholds.max_base_height_ratio:g}",
                )
            )
        if self.pixels is not None:
            from .pixel_match import describe

            rows.extend(describe(self.pixels))
        scale = self.scale if self.scale is not None and self.scale.used else None
        gsd = Distribution.of(self.gsd_cm)
        if gsd is not None:
            text = f"median {gsd.median:.2f} cm ({gsd.min:.2f}-{gsd.max:.2f} cm)"
            if scale is not None:
                text += " from the image scale measured in the pixels; " + (
                    f"the tags give {scale.tagged_gsd_cm:.2f} cm"
                )
            rows.append(("GSD", text))
        h = Distribution.of(self.height_agl_m)
        if h is not None:
            text = f"median {h.median:.1f} m ({h.min:.1f}-{h.max:.1f} m)"
            if scale is not None and scale.blame is Blame.HEIGHTS:
                text += f" from the image scale; the tags give {scale.tagged_height_m:.1f} m"
            elif scale is not None and scale.blame is Blame.EITHER:
                text += f" as tagged; {scale.measured_height_m:.1f} m if the camera is right"
            rows.append(("height above ground", text))
        if scale is not None and scale.blame is not Blame.HEIGHTS:
            rows.append(
                (
                    "focal length",
                    f"{scale.measured_focal_px:.0f} px from the image scale measured in the pixels"
                    + (" if the heights are right" if scale.blame is Blame.EITHER else "")
                    + f"; the camera assumed has {scale.tagged_focal_px:.0f} px",
                )
            )
        speed = Distribution.of(self.stereo.speed_m_s) if self.stereo.speed_m_s is not None else None
        if self.stereo.speed_m_s is None:
            rows.append(("ground speed", "not measured (no capture times)"))
        elif speed is None:
            rows.append(("ground speed", "unknown (no two frames of a line close enough in time)"))
        else:
            unknown = int(np.isnan(self.stereo.speed_m_s).sum())
            text = f"median {speed.median:.1f} m/s ({speed.min:.1f}-{speed.max:.1f} m/s)"
            rows.append(("ground speed", text + (f", unknown for {unknown} frames" if unknown else "")))
        blur = Distribution.of(self.stereo.blur_px) if self.stereo.blur_px is not None else None
        if self.stereo.speed_m_s is None:
            rows.append(("motion blur", "not computed (no capture times)"))
        elif self.stereo.blur_px is None:
            rows.append(("motion blur", "not computed (no exposure time in the images or the camera)"))
        elif blur is None:
            rows.append(("motion blur", "blur not computed for any frame (speed or exposure unknown)"))
        else:
            unknown_blur = int(np.isnan(self.stereo.blur_px).sum())
            text = f"median {blur.median:.2f} px, max {blur.max:.2f} px (where worst in each frame)"
            if unknown_blur:
                text += f"; blur not computed for {unknown_blur} frames (speed or exposure unknown)"
            rows.append(("motion blur", text))
        rows.append(
            (
                "convergent frames",
                f"{self.stereo.convergent_pct:.0f} %" + (" (doming risk)" if self.stereo.doming_risk else ""),
            )
        )
        return rows

    def as_dict(self) -> dict[str, Any]:
        """report.json: the same figures as the HTML report (units in every key)."""
        plan = self.plan
        frames = self.frames
        per_frame: list[dict[str, Any]] = []
        for k in range(len(frames)):
            row: dict[str, Any] = {
                "name": frames.name[k],
                "lon_deg": float(frames.lon_deg[k]),
                "lat_deg": float(frames.lat_deg[k]),
                f"alt_{frames.alt_reference.value}_m": float(frames.alt_m[k]),
                "height_agl_m": float(self.height_agl_m[k]),
                "yaw_deg": float(frames.yaw_deg[k]),
                "pitch_deg": float(frames.pitch_deg[k]),
                "roll_deg": float(frames.roll_deg[k]),
                "gsd_cm": float(self.gsd_cm[k]),
            }
            if self.stereo.speed_m_s is not None:
                row["speed_m_s"] = float(self.stereo.speed_m_s[k])
            if self.stereo.blur_px is not None:
                row["blur_px"] = float(self.stereo.blur_px[k])
            per_frame.append(row)
        bh = Distribution.of(self.stereo.pair_base_height_ratio)
        angle = Distribution.of(self.stereo.pair_intersection_deg)
        return {
            "verdict": "pass" if self.passed else "fail",
            "passed": self.passed,
            "exit_code": 0 if self.passed else 1,  # what `sfap check` exits with (sfap.cli)
            "reasons": list(self.reasons),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "thresholds": self.thresholds.as_dict(),
            "frames": {
                "count": len(frames),
                "camera_id": frames.camera.id,
                "camera_name": frames.camera.name,
                "camera_source": self.camera_source or None,
                "attitude_source": frames.attitude_source.value,
                "altitude_reference": frames.alt_reference.value,
                "unpositioned": list(self.unpositioned),
                "left_out": [{"name": name, "reason": why} for name, why in self.left_out],
            },
            "ground": self.ground_description,
            "area": {
                "source": self.area_source,
                "area_m2": self.area_m2,
                "crs": self.output_crs()[0],
                "cell_m": self.cell_m,
                "extent_m": list(self.extent_in_output_crs()),
                "geojson_crs": "EPSG:4326 (WGS 84, longitude/latitude; RFC 7946)",
                "computed_in": self.frame.crs.to_string(),
            },
            "coverage": {
                "seen_by_at_least_pct": {str(k): v for k, v in self.seen_pct.items()},
                "gap_count": len(self.gaps),
                "gap_area_m2": self.gap_area_m2,
                "gaps": [
                    {
                        "index": g.index,
                        "area_m2": g.area_m2,
                        "centroid_lon_deg": g.centroid_lon_deg,
                        "centroid_lat_deg": g.centroid_lat_deg,
                    }
                    for g in self.gaps
                ],
            },
            "overlap": {
                "forward_pct": self.stereo.forward_overlap_pct.as_dict()
                if self.stereo.forward_overlap_pct
                else None,
                "side_pct": self.stereo.side_overlap_pct.as_dict() if self.stereo.side_overlap_pct else None,
                "plan_front_overlap_pct": plan.planned.summary.front_overlap_pct if plan else None,
                "plan_side_overlap_pct": plan.planned.summary.side_overlap_pct if plan else None,
            },
            "stereo": {
                "pair_count": int(self.stereo.pair_index.shape[0]),
                "base_height_ratio": bh.as_dict() if bh else None,
                "base_height_ratio_along_line": (
                    d.as_dict() if (d := self.base_height_along_line) is not None else None
                ),
                "base_height_ratio_across_lines": (
                    d.as_dict() if (d := self.base_height_across_lines) is not None else None
                ),
                "intersection_angle_deg": angle.as_dict() if angle else None,
                "good_pair_area_pct": self.stereo.good_pair_pct,
                "good_pair_basis": self.stereo.good_pair_basis,
                "convergent_frames_pct": self.stereo.convergent_pct,
                "doming_risk": self.stereo.doming_risk,
            },
            "pixels": self.pixels.as_dict() if self.pixels is not None else None,
            "scale": self.scale.as_dict() if self.scale is not None else None,
            "gsd_cm": (d.as_dict() if (d := Distribution.of(self.gsd_cm)) else None),
            "height_agl_m": (d.as_dict() if (d := Distribution.of(self.height_agl_m)) else None),
            "speed_m_s": (
                d.as_dict()
                if self.stereo.speed_m_s is not None and (d := Distribution.of(self.stereo.speed_m_s))
                else None
            ),
            "blur_px": (
                d.as_dict()
                if self.stereo.blur_px is not None and (d := Distribution.of(self.stereo.blur_px))
                else None
            ),
            "flagged_frames": [{"name": f.name, "kind": f.kind, "detail": f.detail} for f in self.flagged],
            "plan": (
                {
                    "folder": str(plan.planned.folder),
                    "name": plan.planned.name,
                    "camera_id": plan.camera.id,
                    "altitude_agl_m": plan.planned.summary.altitude_agl_m,
                    "gsd_cm": plan.planned.summary.gsd_cm,
                    "front_overlap_pct": plan.planned.summary.front_overlap_pct,
                    "side_overlap_pct": plan.planned.summary.side_overlap_pct,
                }
                if plan
                else None
            ),
            "stats": self.stats,
            "per_frame": per_frame,
        }
