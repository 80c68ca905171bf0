"""The result of planning a survey: what every writer (formats, map, summary) reads. Types only:
no planning here (that is planner.survey and planner.corridor); the files they are written to and
read back from are planner.plan_folder.

Geometry is held in the survey's :class:`~planner.geo.LocalFrame` (metres); lon/lat columns
are filled in once, at the end of planning, so writers never transform coordinates themselves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .camera import Camera, Orientation
from .geo import LocalFrame
from .kinds import PassKind
from .mission import HomePosition, Mission

if TYPE_CHECKING:
    from .mission_builder import PassPlan
    from .spec import MissionSpec
    from .terrain import Dem


@dataclass(frozen=True, kw_only=True)
class FlightLine:
    """One straight survey line of a pass, in flight order.

    ``start_xy_m``/``end_xy_m`` bound the camera-on segment (where photos are taken);
    ``entry_xy_m``/``exit_xy_m`` include the turnaround extensions the vehicle flies.
    """

    pass_index: int
    line_index: int
    start_xy_m: tuple[float, float]
    end_xy_m: tuple[float, float]
    entry_xy_m: tuple[float, float]
    exit_xy_m: tuple[float, float]
    heading_deg: float  # bearing of flight, degrees clockwise from true north

    @property
    def length_m(self) -> float:
        return float(np.hypot(self.end_xy_m[0] - self.start_xy_m[0], self.end_xy_m[1] - self.start_xy_m[1]))


@dataclass(frozen=True, kw_only=True)
class FlightPass:
    """A set of parallel lines flown with one camera pose (nadir, crosshatch or one oblique)."""

    index: int
    kind: PassKind
    name: str  # e.g. "nadir", "crosshatch", "oblique 30 deg looking 90 deg"
    direction_deg: float  # true bearing of the lines, 0-180
    tilt_deg: float  # camera off nadir, 0 for nadir passes
    look_heading_deg: float | None  # true bearing the camera looks toward (obliques), else None
    alt_agl_m: float
    line_spacing_m: float
    trigger_distance_m: float
    lines: tuple[FlightLine, ...]
    near_gsd_cm: float  # finest GSD in the frame (bottom edge for obliques; centre for nadir)
    far_gsd_cm: float  # coarsest GSD in the frame


@dataclass(frozen=True, kw_only=True)
class Stations:
    """Every planned exposure, one row each, in flight order (columns are numpy arrays).

    - ``pass_index``, ``line_index``: int32, the pass and the line within it.
    - ``x_m``, ``y_m``: position in the local frame; ``lon_deg``, ``lat_deg``: WGS84.
    - ``alt_rel_home_m``: commanded altitude above home; ``alt_agl_m``: above the ground below.
    - ``heading_deg``: true bearing of flight; ``look_heading_deg``: true bearing the optical axis
      points toward (equals ``heading_deg`` for nadir frames); ``tilt_deg``: off nadir.
    - ``gsd_cm``: GSD where the optical axis meets the ground.
    - ``footprint_xy_m``: (N, 4, 2) ground corners in the local frame, order: image top-left,
      top-right, bottom-right, bottom-left; ``footprint_lonlat_deg``: the same in lon/lat.
    """

    pass_index: NDArray[np.int32]
    line_index: NDArray[np.int32]
    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    lon_deg: NDArray[np.float64]
    lat_deg: NDArray[np.float64]
    alt_rel_home_m: NDArray[np.float64]
    alt_agl_m: NDArray[np.float64]
    heading_deg: NDArray[np.float64]
    look_heading_deg: NDArray[np.float64]
    tilt_deg: NDArray[np.float64]
    gsd_cm: NDArray[np.float64]
    footprint_xy_m: NDArray[np.float64]
    footprint_lonlat_deg: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.x_m.shape[0])


@dataclass(frozen=True, kw_only=True)
class Summary:
    """The numbers that justify a plan; ``as_dict`` is summary.json."""

    name: str
    area_m2: float
    camera_id: str
    orientation: str
    gsd_cm: float
    gsd_along_cm: float
    gsd_across_cm: float
    altitude_agl_m: float
    scale_number: float
    footprint_along_m: float
    footprint_across_m: float
    front_overlap_pct: float
    side_overlap_pct: float
    air_base_m: float
    line_spacing_m: float
    trigger_distance_m: float
    exposure_interval_s: float
    speed_m_s: float
    max_speed_m_s: float
    max_speed_trigger_m_s: float
    max_speed_blur_m_s: float | None
    base_height_ratio: float
    intersection_angle_deg: float
    depth_precision_m: float
    direction_deg: float
    pass_count: int
    line_count: int
    photo_count: int
    flight_distance_m: float
    flight_time_s: float
    item_count: int
    crs: str
    max_item_count: int = 0  # the autopilot's mission capacity assumed (planner.summary)
    stereo_seen_2_pct: float = 0.0  # share of the area seen by >= 2 nadir frames (planner.coverage)
    stereo_seen_3_pct: float = 0.0  # share seen by >= 3 nadir frames
    stereo_seen_3_target_pct: float = 0.0  # the share >= 3 the plan promises (0: overlap too low)
    warnings: tuple[str, ...] = ()
    terrain: dict[str, object] | None = None  # planner.terrain_follow.TerrainSummary, with a DEM
    corridor: dict[str, object] | None = None  # planner.corridor: width, centre line, line offsets
    vehicle_parameters: tuple[dict[str, object], ...] = ()  # planner.vehicle_params: what to set

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {}
        for key in self.__dataclass_fields__:
            value = getattr(self, key)
            out[key] = list(value) if isinstance(value, tuple) else value
        return out


@dataclass(frozen=True, kw_only=True)
class SurveyPlan:
    """Everything planned for one mission spec."""

    name: str
    camera: Camera
    orientation: Orientation
    frame: LocalFrame
    area_xy: Polygon | MultiPolygon  # the area to cover, holes and exclusions removed
    area_lonlat: Polygon | MultiPolygon
    exclusions_xy: tuple[Polygon, ...]  # holes of the area and extra exclusion zones
    exclusions_lonlat: tuple[Polygon, ...]
    home: HomePosition
    home_xy_m: tuple[float, float]
    passes: tuple[FlightPass, ...]
    stations: Stations
    path_xy_m: NDArray[np.float64]  # (M, 2) the whole flown path, take-off to return
    path_lonlat_deg: NDArray[np.float64]
    mission: Mission
    summary: Summary
    warnings: tuple[str, ...] = field(default=())
    #: What the mission was built from, so that parts of it can be built again as sorties or a
    #: resume plan (planner.sorties); None for plans not made by planner.survey.
    layout: PlanLayout | None = field(default=None, compare=False, repr=False)

    @property
    def entry_xy_m(self) -> tuple[float, float]:
        """Where the first survey line starts (its entry, turnaround included)."""
        return self.passes[0].lines[0].entry_xy_m


@dataclass(frozen=True, kw_only=True)
class PlanLayout:
    """The inputs of planner.mission_builder.build_mission (and of terrain following) for a plan."""

    spec: MissionSpec
    alt_agl_m: float
    speed_m_s: float
    pass_plans: tuple[PassPlan, ...]
    true_north_grid_deg: float
    dem: Dem | None = None
    footprint_scale: float = 1.0
