"""What map.png is drawn from: the part of a plan the map shows, as plain arrays, shapely shapes
and texts (:class:`MapPlan`), taken from a :class:`~planner.plan.SurveyPlan` by :func:`map_view`.

A MapPlan is rebuilt in another process with numpy and shapely alone. ``sfap plan`` draws map.png
in a helper process (planner.aside) that imports only those, Pillow and the drawing
(planner.maprender): started before the planner is imported, it is ready long before the plan
is, instead of importing the whole planner (pyproj, every dataclass) to read a pickled SurveyPlan
while the plan waits for it (BENCHMARKS.md, "Small plans").

The field names are the plan's own (``passes``, ``lines``, ``stations``...), so that the layout
of the map (planner.maplayout) reads a plan or its view alike.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .kinds import PassKind

if TYPE_CHECKING:
    from .plan import FlightLine, FlightPass, Stations, SurveyPlan


@dataclass(frozen=True)
class MapLine:
    """A camera-on segment as the map draws it (planner.plan.FlightLine)."""

    line_index: int
    start_xy_m: tuple[float, float]
    end_xy_m: tuple[float, float]
    entry_xy_m: tuple[float, float]
    heading_deg: float


@dataclass(frozen=True)
class MapPass:
    """A pass as the map colours and counts it (planner.plan.FlightPass)."""

    index: int
    kind: PassKind
    alt_agl_m: float
    tilt_deg: float
    look_heading_deg: float | None
    line_spacing_m: float
    trigger_distance_m: float
    lines: tuple[MapLine, ...]


@dataclass(frozen=True)
class MapStations:
    """The stations' columns the map draws (planner.plan.Stations)."""

    pass_index: NDArray[np.int32]
    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    footprint_xy_m: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.x_m.shape[0])


@dataclass(frozen=True)
class MapPlan:
    """Everything map.png shows of a plan: its geometry in the plan's local frame, its title,
    header and caption texts (which need the plan's summary and projection), and its sorties'
    stations (numbered from 1)."""

    name: str
    home_xy_m: tuple[float, float]
    area_xy: Polygon | MultiPolygon
    exclusions_xy: tuple[Polygon, ...]
    passes: tuple[MapPass, ...]
    stations: MapStations
    path_xy_m: NDArray[np.float64]
    header: str
    caption: str
    sorties: tuple[MapStations, ...] = ()


def _line(line: FlightLine) -> MapLine:
    return MapLine(line.line_index, line.start_xy_m, line.end_xy_m, line.entry_xy_m, line.heading_deg)


def _pass(p: FlightPass) -> MapPass:
    return MapPass(
        p.index,
        p.kind,
        p.alt_agl_m,
        p.tilt_deg,
        p.look_heading_deg,
        p.line_spacing_m,
        p.trigger_distance_m,
        tuple(_line(ln) for ln in p.lines),
    )


def _stations(st: Stations) -> MapStations:
    return MapStations(st.pass_index, st.x_m, st.y_m, st.footprint_xy_m)


def map_view(plan: SurveyPlan, sorties: Sequence[SurveyPlan] = ()) -> MapPlan:
    """The map's view of ``plan`` and of its ``sorties`` (their own plans, numbered from 1)."""
    header, caption = map_texts(plan)
    geometry = map_geometry(
        name=plan.name,
        home_xy_m=plan.home_xy_m,
        area_xy=plan.area_xy,
        exclusions_xy=plan.exclusions_xy,
        passes=plan.passes,
        stations=plan.stations,
        path_xy_m=plan.path_xy_m,
        sorties=sorties,
    )
    return dataclasses.replace(geometry, header=header, caption=caption)


def map_geometry(
    *,
    name: str,
    home_xy_m: tuple[float, float],
    area_xy: Polygon | MultiPolygon,
    exclusions_xy: tuple[Polygon, ...],
    passes: Sequence[FlightPass],
    stations: Stations,
    path_xy_m: NDArray[np.float64],
    sorties: Sequence[SurveyPlan] = (),
) -> MapPlan:
    """The map's view of a plan from its parts (a :class:`~planner.plan.SurveyPlan`'s fields of
    those names), before the plan itself exists: its header and caption are empty (they need
    the plan's summary: :func:`map_texts`)."""
    return MapPlan(
        name=name,
        home_xy_m=home_xy_m,
        area_xy=area_xy,
        exclusions_xy=exclusions_xy,
        passes=tuple(_pass(p) for p in passes),
        stations=_stations(stations),
        path_xy_m=path_xy_m,
        header="",
        caption="",
        sorties=tuple(_stations(s.stations) for s in sorties),
    )


def map_texts(plan: SurveyPlan) -> tuple[str, str]:
    """The map's header and caption of ``plan`` (planner.maplayout)."""
    from .maplayout import caption_text, header_text

    return header_text(plan), caption_text(plan)


def write_map_png(view: MapPlan, path: str | os.PathLike[str]) -> None:
    """map.png of ``view`` written atomically to ``path`` (planner.maprender.write_png). Named
    here, in a module light to import, so that a helper process is sent this function by name
    without this process importing Pillow and the drawing."""
    from .maprender import write_png

    write_png(view, path)


def write_map_png_when_told(view: MapPlan, receive: Callable[[], tuple[str, str, str]]) -> None:
    """map.png of ``view`` (:func:`map_geometry`: no header nor caption yet), all of it but those
    drawn at once; then its header, caption and the path to write it to, from ``receive()``
    (planner.aside.Helper.start: `sfap plan` draws the map while the plan's summary is made)."""
    from .maprender import draw_body, write_finished

    body = draw_body(view)
    header, caption, path = receive()
    write_finished(body, header, caption, path)
