"""Fixtures shared by the processing tests."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from planner.plan_folder import write_outputs
from planner.spec import load_spec
from planner.survey import plan_survey

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


@pytest.fixture(scope="module")
def gully(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    """The bardenas-gully mission planned (the SurveyPlan) and its plan folder."""
    plan = plan_survey(load_spec(MISSIONS / "bardenas-gully.toml"))
    folder = tmp_path_factory.mktemp("gully") / "plan"
    write_outputs(plan, folder)
    return plan, folder
