"""`--run` on real blocks (slow: COLMAP reconstructions at a reduced size to stay within minutes).

garfield_rgb: 28 frames with GPS and real gaps; copr_kap: 41 kite frames without GPS, placed by
its ground control alone. The oracles: the project reconstructs in pycolmap as written (its
models are read back from disk), every frame is either registered or named with its match count,
and on copr_kap the surveyed distances between check points, which the fit never saw.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pycolmap
import pytest
from shared_data import SHARED_DATA

from processing.handoff.pipeline import Engine, HandoffOptions, handoff
from processing.handoff.prepare import GroundOptions

GARFIELD_GROUND_M = 258.0


@pytest.mark.slow
def test_garfield_runs_and_names_every_frame(tmp_path: Path) -> None:
    result = handoff(
        SHARED_DATA / "garfield_rgb",
        tmp_path / "work",
        HandoffOptions(
            engine=Engine.COLMAP,
            run=True,
            ground=GroundOptions(ground_elevation_m=GARFIELD_GROUND_M),
            max_image_size_px=640,
            max_features=2000,
        ),
    )
    ql = json.loads((tmp_path / "work" / "report.json").read_text())["quicklook"]
    assert result.exit_code == (0 if ql["reconstructs"] else 1)
    names = {p.name for p in (SHARED_DATA / "garfield_rgb").glob("*.JPG")}
    unregistered = {r["name"] for r in ql["not_registered"]}
    assert set(ql["registered"]) | unregistered == names
    assert not set(ql["registered"]) & unregistered
    assert all(isinstance(r["verified_matches"], int) for r in ql["not_registered"])
    # The models on disk are COLMAP's own: pycolmap reads the largest back with the frames reported.
    models = sorted((tmp_path / "work" / "sparse").iterdir())
    largest = max(
        (pycolmap.Reconstruction(str(m)) for m in models if m.name.isdigit()),
        key=lambda r: r.num_reg_images(),
    )
    assert largest.num_reg_images() == ql["frames_registered"]
    assert largest.num_points3D() == ql["points3d"]
    cmp_ = ql["check_vs_reconstruction"]
    if cmp_ is not None:
        assert 0 <= cmp_["covered_but_empty_cells"] <= cmp_["covered_cells"]
    html = (tmp_path / "work" / "report.html").read_text()
    assert "frames registered" in html


@pytest.mark.slow
def test_copr_kap_is_placed_by_control_alone(tmp_path: Path) -> None:
    copr = SHARED_DATA / "copr_kap"
    result = handoff(
        copr / "images",
        tmp_path / "work",
        HandoffOptions(
            engine=Engine.COLMAP,
            run=True,
            gcp=copr / "gcp_list.txt",
            check_points="3",
            max_image_size_px=640,
            max_features=2000,
        ),
    )
    acc = result.report["accuracy"]
    unused = {u["name"]: u["reason"] for u in acc["unused_points"]}
    assert any(n.startswith("gcp00: seen in 1 image") for n in acc["notes"])  # listed, not used
    assert "re-mark it" in unused["gcp04"]  # its three marks disagree by hundreds of pixels
    check = acc["check"]
    assert check["n_points"] >= 2
    # The surveyed positions are averaged GPS (GPS_average.txt): metre-level, so the check points
    # come back within a few metres, and the distances between them within a few percent.
    assert check["rmse_horizontal_m"] < 3.0
    for d in acc["check_distances"]:
        assert abs(d["difference_m"]) < 0.1 * d["surveyed_m"] + 0.5
    assert acc["control"]["range_m"] > 5.0  # the kite is above the ground, not below it
    assert np.isfinite(acc["similarity"]["scale"])
