"""The kinds of flight pass, standard library only: the plan (planner.plan) and what is drawn from
it in another process (planner.mapview) share them without that process importing the planner."""

from __future__ import annotations

from enum import StrEnum


class PassKind(StrEnum):
    NADIR = "nadir"
    CROSSHATCH = "crosshatch"
    OBLIQUE = "oblique"
