"""map.png: its header and its legend count the same lines, and the planner's summary agrees
(issue 13). The planner counts rows from its own line layout; the map groups the camera-on
segments by their offset across the pass: two constructions that must meet."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from planner.mapplot import pass_line_count, render_map_figure
from planner.spec import load_spec
from planner.survey import plan_survey

MISSIONS = sorted((Path(__file__).resolve().parents[2] / "missions").glob("*.toml"))


@pytest.mark.parametrize("mission", MISSIONS, ids=[m.stem for m in MISSIONS])
def test_header_and_legend_agree_on_the_number_of_lines(mission: Path) -> None:
    plan = plan_survey(load_spec(mission))
    fig = render_map_figure(plan)
    header = " ".join(t.get_text() for t in fig.texts)
    match = re.search(r"([\d,]+) lines?(?: in ([\d,]+) segments)?, \d+ pass", header)
    assert match is not None, header
    header_lines = int(match.group(1).replace(",", ""))
    legend = fig.axes[0].get_legend()
    assert legend is not None
    legend_lines = 0
    for text in legend.get_texts():
        found = re.match(r"camera on, \w+ \(([\d,]+) lines?", text.get_text())
        if found:
            legend_lines += int(found.group(1).replace(",", ""))
    assert header_lines == legend_lines == plan.summary.line_count
    segments = sum(len(p.lines) for p in plan.passes)
    assert (match.group(2) is not None) == (segments != header_lines)
    if match.group(2) is not None:
        assert int(match.group(2).replace(",", "")) == segments


def test_pass_line_count_groups_segments_of_one_row() -> None:
    plan = plan_survey(load_spec(MISSIONS[0]))
    nadir = plan.passes[0]
    # a row split into two pieces (a hole) is still one line; a shifted copy is another line
    first = nadir.lines[0]
    mid = ((first.start_xy_m[0] + first.end_xy_m[0]) / 2, (first.start_xy_m[1] + first.end_xy_m[1]) / 2)
    halves = (
        type(first)(**{**first.__dict__, "end_xy_m": mid}),
        type(first)(**{**first.__dict__, "start_xy_m": mid}),
    )
    split = type(nadir)(**{**nadir.__dict__, "lines": halves})
    assert pass_line_count(split) == 1
    dx, dy = first.end_xy_m[0] - first.start_xy_m[0], first.end_xy_m[1] - first.start_xy_m[1]
    norm = (dx * dx + dy * dy) ** 0.5
    shift = (-dy / norm * 0.05, dx / norm * 0.05)  # 5 cm across the line
    moved = type(first)(
        **{
            **first.__dict__,
            "start_xy_m": (first.start_xy_m[0] + shift[0], first.start_xy_m[1] + shift[1]),
            "end_xy_m": (first.end_xy_m[0] + shift[0], first.end_xy_m[1] + shift[1]),
        }
    )
    assert pass_line_count(type(nadir)(**{**nadir.__dict__, "lines": (first, moved)})) == 2
