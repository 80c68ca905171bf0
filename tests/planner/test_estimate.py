"""The size estimate from geometry alone (planner.estimate), against the plans themselves: the
photos, lines and flight time the planner then lays out, on the examples and random shapes; a plan
beyond the limit is refused at once, nothing written, and planned when the flag raises the limit."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from survey_oracles import MISSIONS, make_spec
from test_survey import to_lonlat_polygon

from planner.errors import SpecError
from planner.spec import load_spec
from planner.survey import estimate_survey, plan_polygons, plan_survey
from sfap.cli import cli


@pytest.mark.parametrize(
    "name", ["bardenas-gully", "field-concave", "field-multiscale", "huesca-plane-block", "quarry-block"]
)
def test_the_estimate_is_near_what_the_examples_plan(name: str) -> None:
    spec = load_spec(MISSIONS / f"{name}.toml")
    guess = estimate_survey(spec)
    assert guess is not None
    plan = plan_survey(spec)
    s = plan.summary
    assert 0.75 * s.photo_count <= guess.photos <= 1.35 * s.photo_count, (guess.photos, s.photo_count)
    assert 0.8 * s.line_count <= guess.lines <= 1.2 * s.line_count, (guess.lines, s.line_count)
    assert 0.6 * s.flight_time_s <= guess.flight_hours * 3600 <= 1.3 * s.flight_time_s
    if name == "huesca-plane-block":  # a plane's run-in (one L1 period) and U-turns, not the turnaround
        assert guess.flight_hours * 3600 >= 0.8 * s.flight_time_s, (guess.flight_hours, s.flight_time_s)
    assert 0.5 * s.item_count <= guess.items <= 1.3 * s.item_count, (guess.items, s.item_count)


@settings(max_examples=8, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    width=st.floats(400.0, 1200.0),
    height=st.floats(400.0, 1200.0),
    notch=st.floats(0.0, 0.6),
    front=st.sampled_from([70, 80]),
    side=st.sampled_from([60, 70]),
)
def test_the_estimate_follows_the_photos_of_random_blocks(
    width: float, height: float, notch: float, front: int, side: int
) -> None:
    spec = make_spec({"front_overlap_pct": front, "side_overlap_pct": side})
    w, h = width, height
    outline = [(0, 0), (w, 0), (w, h), (w * (1 - notch), h), (w * (1 - notch), h * (1 - notch)), (0, h)]
    plan = plan_polygons(spec, [to_lonlat_polygon(outline)], [])
    from planner import estimate as est
    from planner import survey

    site = survey.steps.project_area(spec, [to_lonlat_polygon(outline)], [], what="area")
    alt, _ = survey.steps.flying_height(spec)
    guess = est.estimate(
        spec, site.area_xy, survey._pass_geometry(spec, survey._all_pass_defs(spec, site), alt)
    )
    assert 0.7 * len(plan.stations) <= guess.photos <= 1.4 * len(plan.stations), (
        guess.photos,
        len(plan.stations),
    )


def _big_square(folder: Path) -> Path:
    """A 1.5 x 1.5 km block at 1 cm: a few thousand photos."""
    ring = [list(p) for p in to_lonlat_polygon([(0, 0), (1500, 0), (1500, 1500), (0, 1500)]).exterior.coords]
    (folder / "square.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    spec = folder / "square.toml"
    spec.write_text(
        'name = "square"\narea = "square.geojson"\n[camera]\nmodel = "dji-phantom-4-pro"\n'
        "[survey]\ngsd_cm = 1.5\nfront_overlap_pct = 75\nside_overlap_pct = 65\nspeed_m_s = 5\n"
        '[vehicle]\ntype = "multirotor"\nmax_alt_agl_m = 120\n'
    )
    return spec


def test_a_plan_beyond_the_limit_is_refused_at_once_and_the_flag_raises_it(tmp_path: Path) -> None:
    spec_file = _big_square(tmp_path)
    guess = estimate_survey(load_spec(spec_file))
    assert guess is not None and guess.photos > 2000
    with pytest.raises(SpecError, match=r"split the area into at least \d+ blocks.*coarser gsd_cm"):
        plan_survey(load_spec(spec_file), max_photos=1000)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(spec_file), "-o", str(out), "--max-photos", "1000"])
    assert result.exit_code == 2, result.output
    assert f"about {guess.photos:,} photos" in result.stderr and "--max-photos" in result.stderr
    assert "Traceback" not in result.output and not out.exists()
    result = CliRunner().invoke(
        cli, ["plan", str(spec_file), "-o", str(out), "--max-photos", str(guess.photos + 1), "--no-progress"]
    )
    assert result.exit_code == 0, result.output
    assert (out / "summary.json").is_file()


def test_a_long_plan_shows_its_estimate_and_steps_on_stderr(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sfap.commands.plan as command

    monkeypatch.setattr(command, "ANNOUNCE_PHOTOS", 10)  # as if this small plan took long
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(MISSIONS / "bardenas-gully.toml"), "-o", str(out)])
    assert result.exit_code == 0, result.output
    lines = result.stderr.splitlines()
    assert lines[0].startswith("planning about ") and "photos" in lines[0]
    assert any("laying out the lines" in line for line in lines)
    assert any("building the flight path" in line for line in lines)
    quiet = CliRunner().invoke(cli, ["plan", str(MISSIONS / "bardenas-gully.toml"), "-o", str(tmp_path / "q"),
                                     "--no-progress"])  # fmt: skip
    assert quiet.exit_code == 0 and "planning about" not in quiet.stderr


@pytest.mark.parametrize("spec", ["bardenas-gully.toml", "quarry-block.toml", "bardenas-gully-terrain.toml"])
def test_the_plan_announces_the_estimate_once_before_laying_out_its_lines(spec: str) -> None:
    """plan_spec's ``announce`` is given, once and before the first step of the layout, the
    estimate :func:`estimate_survey` makes on its own from the spec."""
    from planner.plan_run import plan_spec

    events: list[object] = []
    plan_spec(MISSIONS / spec, announce=events.append, stage=events.append)
    assert events[0] == estimate_survey(load_spec(MISSIONS / spec))
    assert sum(not isinstance(e, str) for e in events) == 1
    assert any(isinstance(e, str) and e.startswith("laying out the lines") for e in events[1:])


def test_a_corridor_is_not_announced() -> None:
    from planner.plan_run import plan_spec

    events: list[object] = []
    plan_spec(MISSIONS / "bardenas-stream-corridor.toml", announce=events.append)
    assert events == [] and estimate_survey(load_spec(MISSIONS / "bardenas-stream-corridor.toml")) is None
