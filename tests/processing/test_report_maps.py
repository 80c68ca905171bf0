"""Gap labels on the report's map never overlap, however close the gaps are."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from processing.report_maps import place_labels


@pytest.mark.parametrize("count", [2, 12, 40])
def test_labels_of_clustered_gaps_do_not_overlap(count: int) -> None:
    figure = Figure(figsize=(7.0, 6.0), dpi=110, layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    ax.set_xlim(0, 1000)
    ax.set_ylim(0, 1000)
    rng = np.random.default_rng(count)
    # Gaps within a few metres of each other on a 1 km map: every label wants the same spot.
    # Half at the centre, half at the map's lower edge, where a label pushed down would leave it.
    anchors = [(500 + rng.normal(0, 3), (500 if k % 2 else 5) + abs(rng.normal(0, 3))) for k in range(count)]
    labels = place_labels(ax, anchors, [str(k + 1) for k in range(count)])
    renderer = figure.canvas.get_renderer()
    figure.canvas.draw()  # the final layout, as savefig renders it
    boxes = [Text.get_window_extent(label, renderer) for label in labels]
    overlapping = [(i, j) for i in range(count) for j in range(i) if boxes[i].overlaps(boxes[j])]
    assert overlapping == []
    # ... and every label inside the map.
    inside = ax.get_window_extent(renderer)
    assert all(
        inside.x0 <= b.x0 and b.x1 <= inside.x1 and inside.y0 <= b.y0 and b.y1 <= inside.y1 for b in boxes
    )
    # Each label still points at its own gap (the anchor is the gap's point).
    for label, anchor in zip(labels, anchors, strict=True):
        assert label.xy == pytest.approx(anchor)
    # The first label at the centre (the largest gap there) keeps its place on its anchor; the
    # one on the map's edge moved inside.
    assert labels[1].get_position() == (0, 0)
    assert labels[0].get_position() != (0, 0)
