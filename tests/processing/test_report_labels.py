"""Gap labels on the report's map never overlap, however close the gaps are."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from processing.report import place_labels


@pytest.mark.parametrize("count", [2, 12, 40])
def test_labels_of_clustered_gaps_do_not_overlap(count: int) -> None:
    figure = Figure(figsize=(7.0, 6.0), dpi=110, layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    ax.set_xlim(0, 1000)
    ax.set_ylim(0, 1000)
    rng = np.random.default_rng(count)
    # Gaps within a few metres of each other on a 1 km map: every label wants the same spot.
    anchors = [(500 + rng.normal(0, 3), 500 + rng.normal(0, 3)) for _ in range(count)]
    labels = place_labels(ax, anchors, [str(k + 1) for k in range(count)])
    renderer = figure.canvas.get_renderer()
    figure.canvas.draw()  # the final layout, as savefig renders it
    boxes = [Text.get_window_extent(label, renderer) for label in labels]
    overlapping = [(i, j) for i in range(count) for j in range(i) if boxes[i].overlaps(boxes[j])]
    assert overlapping == []
    # Each label still points at its own gap (the anchor is the gap's point).
    for label, anchor in zip(labels, anchors, strict=True):
        assert label.xy == pytest.approx(anchor)
    # The first (largest) gap keeps its place on its anchor.
    assert labels[0].get_position() == (0, 0)
