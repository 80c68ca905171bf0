"""planner.mapview: the map's view of a plan, drawn in a process that never imports the planner.

`sfap plan` starts map.png's helper (a second interpreter) before it imports the planner and
sends it the plan's :class:`~planner.mapview.MapPlan`: the helper must be able to import the
drawing and rebuild the view with numpy, shapely and Pillow alone, and draw the map the plan
itself gives. Checked in fresh processes (``python -c``), whose modules are their own, and in a
real helper.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pickle
import subprocess
import sys
import textwrap
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from planner.errors import OutputExistsError
from planner.mapview import MapPlan
from planner.plan import SurveyPlan

REPO = Path(__file__).resolve().parents[2]

#: What the helper must not import: the planner's own modules, and the libraries only planning needs.
PLANNING = (
    "pyproj",
    "click",
    "planner.plan",
    "planner.geo",
    "planner.survey",
    "planner.spec",
    "planner.camera",
)


def _run(script: str) -> dict[str, object]:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_the_helper_draws_the_map_without_importing_the_planning(tmp_path: Path) -> None:
    """A real helper, warmed up as `sfap plan` warms it, sent the gully's view: it draws the
    plan's own map and has imported nothing of the planning by the end (its sys.modules)."""
    from planner.mapplot import map_png_bytes
    from planner.mapview import map_view
    from planner.spec import load_spec
    from planner.survey import plan_survey
    from sfap.commands.plan import MAP_WARM_UP

    plan = plan_survey(load_spec(REPO / "missions" / "bardenas-gully.toml"))
    sent = tmp_path / "view.pickle"
    sent.write_bytes(pickle.dumps(map_view(plan), protocol=pickle.HIGHEST_PROTOCOL))
    png, modules = tmp_path / "map.png", tmp_path / "helper.json"
    result = _run(
        f"""
        import json, os, pickle
        from planner.aside import Helper
        from tests.support.aside_jobs import draw_map_then_record
        helper = Helper(warm={MAP_WARM_UP!r})
        view = pickle.loads(open({str(sent)!r}, "rb").read())
        aside = helper.submit(draw_map_then_record, view, {str(png)!r}, {str(modules)!r}, what="map.png")
        spawned = aside.forked
        aside.wait()
        print(json.dumps({{"me": os.getpid(), "spawned": spawned}}))
        """
    )
    helper = json.loads(modules.read_text())
    assert result["spawned"] is True and helper["ppid"] == result["me"]
    assert "PIL.PngImagePlugin" in helper["modules"]  # it did draw and encode
    assert [m for m in PLANNING if m in helper["modules"]] == []
    assert png.read_bytes() == map_png_bytes(plan)


def test_a_view_sent_to_a_fresh_process_draws_the_plans_own_map(tmp_path: Path) -> None:
    """The gully's view, pickled as the helper receives it, read and drawn in a process without
    the planner: the same PNG bytes as the map drawn here from the plan itself."""
    from planner.mapplot import map_png_bytes
    from planner.mapview import map_view
    from planner.spec import load_spec
    from planner.survey import plan_survey

    plan = plan_survey(load_spec(REPO / "missions" / "bardenas-gully.toml"))
    sent = tmp_path / "view.pickle"
    sent.write_bytes(pickle.dumps(map_view(plan), protocol=pickle.HIGHEST_PROTOCOL))
    drawn = tmp_path / "map.png"
    result = _run(
        f"""
        import json, pickle, sys
        import planner.mapview
        view = pickle.loads(open({str(sent)!r}, "rb").read())
        from planner.maprender import write_png
        write_png(view, {str(drawn)!r})
        print(json.dumps({{"loaded": [m for m in {PLANNING!r} if m in sys.modules]}}))
        """
    )
    assert result == {"loaded": []}
    assert drawn.read_bytes() == map_png_bytes(plan)


def _assert_view_of(view: MapPlan, plan: SurveyPlan) -> None:
    """Field by field, by name, the view against the plan it was taken from: every pass, line
    and station column, and the texts the matplotlib map writes from the plan."""
    from planner.maplayout import caption_text, header_text
    from planner.mapview import MapLine, MapPass, MapStations

    for seen, planned in zip(view.passes, plan.passes, strict=True):
        for f in fields(MapPass):
            if f.name != "lines":
                assert getattr(seen, f.name) == getattr(planned, f.name), f.name
        assert len(seen.lines) == len(planned.lines)
        for line, flown in zip(seen.lines, planned.lines, strict=True):
            for f in fields(MapLine):
                assert getattr(line, f.name) == getattr(flown, f.name), f.name
    for f in fields(MapStations):
        assert np.array_equal(getattr(view.stations, f.name), getattr(plan.stations, f.name)), f.name
    assert view.name == plan.name and view.home_xy_m == plan.home_xy_m
    assert view.area_xy.equals_exact(plan.area_xy, 0.0)
    assert view.exclusions_xy == plan.exclusions_xy
    assert np.array_equal(view.path_xy_m, plan.path_xy_m)
    assert (view.header, view.caption) == (header_text(plan), caption_text(plan))
    assert view.sorties == ()


def test_the_view_carries_each_field_the_map_reads_from_the_plan() -> None:
    """The quarry block: nadir, crosshatch and four obliques looking four ways, so that no two
    passes are alike."""
    from planner.mapview import map_view
    from planner.spec import load_spec
    from planner.survey import plan_survey

    plan = plan_survey(load_spec(REPO / "missions" / "quarry-block.toml"))
    assert len({(p.kind, p.look_heading_deg) for p in plan.passes}) == len(plan.passes) == 6
    _assert_view_of(map_view(plan), plan)


@pytest.mark.parametrize("spec", ["quarry-block.toml", "bardenas-gully-terrain.toml"])
def test_the_view_given_when_the_mission_is_built_is_the_plans_own(
    spec: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """planner.survey's ``on_built``: the view handed out before the coverage figures are
    counted (the order recorded) is, but for the texts it cannot have yet, the view of the plan
    it becomes; over terrain, of the attempt kept, the figures counted for it alone."""
    import planner.survey as survey
    from planner.maplayout import caption_text, header_text
    from planner.spec import load_spec

    events: list[str] = []
    views: list[MapPlan] = []
    count = survey.view_shares

    def counting(*args: Any) -> Any:
        events.append("counted")
        return count(*args)

    def on_built(view: MapPlan) -> None:
        events.append("built")
        views.append(view)

    monkeypatch.setattr(survey, "view_shares", counting)
    plan = survey.plan_survey(load_spec(REPO / "missions" / spec), on_built=on_built)
    assert events == ["built", "counted"]
    (early,) = views
    assert (early.header, early.caption) == ("", "")
    _assert_view_of(dataclasses.replace(early, header=header_text(plan), caption=caption_text(plan)), plan)


def test_plan_spec_begins_the_map_during_the_planning_of_a_whole_plan_only(tmp_path: Path) -> None:
    """With a helper, `sfap plan`'s planning begins map.png as soon as the mission is built:
    for a whole plan, and there the same bytes as drawn from the plan; not for a resumed plan,
    sorties or a corridor (drawn at the write as before). A refused folder stops the begun map."""
    from planner.aside import Helper
    from planner.mapplot import map_png_bytes
    from planner.plan_run import plan_spec
    from sfap.commands.plan import MAP_WARM_UP

    cases = [
        ("bardenas-gully.toml", {}, True),
        ("bardenas-gully.toml", {"resume_from": 40}, False),
        ("quarry-block-sorties.toml", {}, False),
        ("bardenas-stream-corridor.toml", {}, False),
    ]
    for k, (spec, options, begins) in enumerate(cases):
        out = tmp_path / f"out{k}"
        with Helper(warm=MAP_WARM_UP) as helper:
            run = plan_spec(REPO / "missions" / spec, helper=helper, **options)  # type: ignore[arg-type]
            assert (run.map_begun is not None) is begins, (spec, options)
            run.write(out, helper=helper)
        if not run.sorties:
            assert (out / "map.png").read_bytes() == map_png_bytes(run.plan), (spec, options)

    with Helper(warm=MAP_WARM_UP) as helper:
        run = plan_spec(REPO / "missions" / "bardenas-gully.toml", helper=helper)
        assert run.map_begun is not None and run.map_begun.pid is not None
        pid = run.map_begun.pid
        with pytest.raises(OutputExistsError):
            run.write(tmp_path / "out0", helper=helper)  # exists: --overwrite not given
    with pytest.raises(ChildProcessError):  # stopped and reaped
        os.waitpid(pid, os.WNOHANG)
