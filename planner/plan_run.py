"""What ``sfap plan`` does, as one library call: a mission spec planned (planner.survey), cut to
what is left after a flight cut short (planner.resume), split into sorties when the vehicle has
an endurance (planner.sorties), and its files written (planner.plan_folder). No geometry here:
only the order of those steps, as the command runs them."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import InputError
from .estimate import PlanEstimate
from .limits import MAX_PHOTOS
from .plan import SurveyPlan
from .spec import MissionSpec

if TYPE_CHECKING:  # planner.sorties is imported only for a vehicle with an endurance
    from .aside import Aside, Helper
    from .mapview import MapPlan
    from .sorties import Sortie


@dataclass(frozen=True, kw_only=True)
class PlanRun:
    """A planned spec: the plan (resumed when asked), its sorties (none when the vehicle has no
    endurance), the station it was resumed from (None: the whole mission), and map.png's
    drawing when it was begun during the planning (:func:`plan_spec` with a helper)."""

    spec: MissionSpec
    plan: SurveyPlan
    sorties: tuple[Sortie, ...] = field(default=())
    resumed_from_station: int | None = None
    map_begun: Aside | None = field(default=None, compare=False)

    @property
    def file_count(self) -> int:
        """How many files :meth:`write` writes (for a progress bar)."""
        from .plan_folder import output_files

        return len(output_files(self.plan)) + sum(len(output_files(s.plan)) for s in self.sorties)

    def write(
        self,
        out_dir: str | os.PathLike[str],
        *,
        overwrite: bool = False,
        progress: Callable[[int], None] | None = None,
        helper: Helper | None = None,
    ) -> list[Path]:
        """Every file of the plan (and of each sortie, in sortie-NN/) into ``out_dir``, all or
        nothing; ``progress(1)`` after each file. map.png is finished by the helper that began
        it during the planning (:attr:`map_begun`), else drawn by ``helper`` (a
        :class:`planner.aside.Helper` warmed with :func:`planner.maprender.prepare`; with
        sorties, each map is drawn aside at its write and the helper is stopped here)."""
        if self.sorties:
            from .sorties import write_with_sorties

            if helper is not None:
                helper.close()
            return write_with_sorties(
                self.plan, self.sorties, Path(out_dir), overwrite=overwrite, progress=progress
            )
        from .plan_folder import write_outputs

        try:
            return write_outputs(
                self.plan,
                out_dir,
                overwrite=overwrite,
                progress=progress,
                helper=helper,
                map_begun=self.map_begun,
            )
        except BaseException:
            if self.map_begun is not None:
                self.map_begun.cancel()  # never sent its texts when the folder was refused
            raise

    def summary(self) -> dict[str, object]:
        """summary.json's figures, with the sorties and the station resumed from."""
        summary = self.plan.summary.as_dict()
        if self.sorties:
            from .sorties import sorties_summary

            summary["sorties"] = sorties_summary(self.plan, self.sorties)
        if self.resumed_from_station is not None:
            summary["resumed_from_station"] = self.resumed_from_station
        return summary


def plan_spec(
    spec_file: str | os.PathLike[str],
    *,
    resume_from: int | None = None,
    resume_record: str | os.PathLike[str] | None = None,
    max_photos: int | None = MAX_PHOTOS,
    announce: Callable[[PlanEstimate], None] | None = None,
    stage: Callable[[str], None] | None = None,
    helper: Helper | None = None,
) -> PlanRun:
    """Plan the mission spec ``spec_file``; with ``resume_from`` (a station, 0-based in flight
    order) or ``resume_record`` (the folder sfap monitor recorded, or its triggers.csv: after
    the last station it reached) only what is left. Sorties when the spec's vehicle has an
    endurance. A block estimated beyond ``max_photos`` photos is refused at once (planner.estimate);
    ``announce(estimate)`` is given the block's estimate before its lines are laid out
    (planner.survey.plan_polygons: not for a corridor); ``stage(what)`` at each step of the
    planning (progress). With a ``helper`` (a :class:`planner.aside.Helper` warmed
    with :func:`planner.maprender.prepare`), map.png is begun there as soon as the mission is
    built (planner.survey.plan_polygons: ``on_built``), while the summary is made, unless the
    plan is resumed, cut into sorties or a corridor: :meth:`PlanRun.write` finishes it."""
    from .resume import last_station_from_record, resume_plan
    from .spec import load_spec
    from .survey import plan_survey

    if resume_from is not None and resume_record is not None:
        raise InputError("give --resume-from or --resume-record, not both")
    spec = load_spec(Path(spec_file))
    map_begun: Aside | None = None

    def begin_map(view: MapPlan) -> None:
        nonlocal map_begun
        from .mapview import write_map_png_when_told

        assert helper is not None
        map_begun = helper.start(write_map_png_when_told, view, what="map.png")

    whole = resume_from is None and resume_record is None and spec.vehicle.endurance_s is None
    try:
        plan = plan_survey(
            spec,
            max_photos=max_photos,
            stage=stage,
            on_built=begin_map if helper is not None and whole else None,
            announce=announce,
        )
    except BaseException:
        if map_begun is not None:
            map_begun.cancel()
        raise
    if resume_record is not None:
        resume_from = last_station_from_record(plan, Path(resume_record)) + 1
        if resume_from >= len(plan.stations):
            raise InputError(
                f"{resume_record}: the record reached the last station ({resume_from - 1}); nothing is "
                f"left to fly"
            )
    if resume_from is not None:
        plan = resume_plan(plan, resume_from)
    sorties: tuple[Sortie, ...] = ()
    if spec.vehicle.endurance_s is not None:
        from .sorties import split_sorties

        if stage is not None:
            stage("splitting into sorties")
        sorties = tuple(split_sorties(plan))
    return PlanRun(
        spec=spec, plan=plan, sorties=sorties, resumed_from_station=resume_from, map_begun=map_begun
    )
