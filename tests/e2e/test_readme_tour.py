"""The README's tour, run exactly as the README shows it: every shell command of the section
"A tour of every command", in order, in a fresh folder with the repository's missions/.

The commands are read from README.md itself (every ```sh block of the section), so the test
fails when the README promises a command that does not run. A line ending in ``&`` is started
in the background, as a shell would, and must end by itself with exit 0 by the end of the tour.
Besides the exit codes, the test holds the tour to what the README says of it: the upload is
verified, the monitor counts every planned photo and misses none, geotag finds the camera clock
offset the simulator was given, and the check passes.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def tour_commands(text: str) -> list[str]:
    """The shell command lines of the README's tour section, comments removed, in order."""
    start = text.index("## A tour of every command")
    end = text.index("\n## ", start + 3)
    section = text[start:end]
    commands: list[str] = []
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        for line in block.splitlines():
            code = re.sub(r"\s+#.*$", "", line).strip()
            if code and not code.startswith("#"):
                commands.append(code)
    return commands


def test_the_tour_section_lists_every_command() -> None:
    commands = tour_commands(README.read_text(encoding="utf-8"))
    names = [shlex.split(c.rstrip("&"))[1] for c in commands]
    assert all(shlex.split(c)[0] == "sfap" for c in commands), commands
    for name in (
        "cameras",
        "plan",
        "sim",
        "upload",
        "download",
        "monitor",
        "clear",
        "geotag",
        "check",
        "handoff",
    ):
        assert name in names, f"the tour runs no `sfap {name}`"
    # the simulator runs in the background and comes before every command that talks to it
    sim = names.index("sim")
    assert commands[sim].endswith("&")
    assert sim < min(names.index(n) for n in ("upload", "download", "monitor", "clear"))


@pytest.mark.slow
def test_readme_tour_runs_as_written(tmp_path: Path) -> None:
    commands = tour_commands(README.read_text(encoding="utf-8"))
    shutil.copytree(ROOT / "missions", tmp_path / "missions")
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env.pop("SFAP_SIGNING_KEY", None)
    background: list[tuple[str, subprocess.Popen[str]]] = []
    outputs: dict[str, list[subprocess.CompletedProcess[str]]] = {}
    try:
        for command in commands:
            name = shlex.split(command.rstrip("&"))[1]
            if command.endswith("&"):
                process = subprocess.Popen(
                    ["bash", "-c", command.rstrip("&").strip()],
                    cwd=tmp_path,
                    env=env,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    text=True,
                )
                background.append((command, process))
                continue
            done = subprocess.run(
                ["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
            )
            assert done.returncode == 0, (
                f"`{command}` exited {done.returncode}:\n{done.stdout}\n{done.stderr}"
            )
            assert "Traceback" not in done.stderr, done.stderr
            outputs.setdefault(name, []).append(done)
        for command, process in background:
            out, _ = process.communicate(timeout=120)
            assert process.returncode == 0, f"`{command}` exited {process.returncode}:\n{out}"
    finally:
        for _, process in background:
            if process.poll() is None:
                process.kill()
                process.communicate()

    sim_command = next(c for c in commands if shlex.split(c)[1] == "sim")
    args = shlex.split(sim_command.rstrip("&"))
    offset_s = float(args[args.index("--camera-offset-s") + 1])
    plan_dir = tmp_path / args[args.index("--plan") + 1]
    planned = int(json.loads((plan_dir / "summary.json").read_text())["photo_count"])

    assert "every item matches" in outputs["upload"][0].stdout
    monitor = outputs["monitor"][0].stdout
    assert f"photos: {planned} of {planned} planned" in monitor, monitor
    assert "stations missed: 0" in monitor, monitor
    frames = sorted((tmp_path / args[args.index("--frames") + 1]).glob("*.JPG"))
    assert len(frames) == planned
    geotag = outputs["geotag"][0].stdout
    found = re.search(r"camera clock offset\s+([+-]\d+\.\d+) s", geotag)
    assert found is not None, geotag
    assert abs(float(found.group(1)) - offset_s) < 0.05
    assert re.search(rf"tagged\s+{planned}\b", geotag), geotag
    check = outputs["check"][0].stdout
    assert check.startswith("PASS"), check
    # Issue 24: the flight check and the plan check of the same nadir block agree on the doming
    # risk (the log has no gimbal angles: the vehicle's pitch is not the gimbal camera's).
    assert "stabilised gimbal" in outputs["geotag"][0].stdout + outputs["geotag"][0].stderr
    convergent = [
        re.search(r"convergent frames\s+(\d+) %( \(doming risk\))?", done.stdout) for done in outputs["check"]
    ]
    assert all(c is not None for c in convergent), [done.stdout for done in outputs["check"]]
    flight, plan = (c.group(2) is not None for c in convergent if c is not None)
    assert flight == plan, [c.group(0) for c in convergent if c is not None]
