"""`sfap gcp-plan --max-photos`: a survey estimated beyond the limit is refused at once, in one
line with the estimate and the fix, nothing written; raising the limit lays the control out."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from sfap.cli import cli

SPEC = Path(__file__).resolve().parents[2] / "missions" / "field-concave.toml"


def test_a_survey_beyond_max_photos_is_refused_and_a_higher_limit_lays_it_out(tmp_path: Path) -> None:
    out = tmp_path / "gcp"
    refused = CliRunner().invoke(cli, ["gcp-plan", str(SPEC), "-o", str(out), "--max-photos", "10"])
    assert refused.exit_code == 2, refused.output
    lines = [line for line in refused.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in refused.output
    assert "photos" in lines[0] and "--max-photos" in lines[0] and "sfap plan" not in lines[0]
    assert not out.exists()
    args = ["gcp-plan", str(SPEC), "-o", str(out), "--max-photos", "100000", "--json"]
    done = CliRunner().invoke(cli, args)
    assert done.exit_code == 0, done.output
    layout = json.loads(done.output[done.output.index("{") :])
    assert layout["gcp_count"] == 8 and layout["check_count"] == 4
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["gcp.geojson", "gcp.kml", "gcp.csv", "gcp.json", "gcp_map.png"]
    )
