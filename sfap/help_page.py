"""What `sfap --help` says, and the page itself written without click.

The command table, the group's text and its options live here, standard library only, and
sfap/cli.py builds the click group from them. `sfap --help` (and `-h`), the page a new user
types first, is written from them by :func:`render` in click's own layout without importing
click, which is most of the command's start-up (benchmarks/plan_vs_flightplan.py, "help").
tests/cli/test_help_page.py holds the page to click's rendering of the same group at every
width, so the two cannot drift apart.
"""

from __future__ import annotations

import os
import sys

#: name -> (module in sfap.commands, one-line help). The order is the order of ``sfap --help``.
COMMANDS: dict[str, tuple[str, str]] = {
    "plan": ("plan", "Plan a survey mission from a mission spec (TOML)."),
    "cameras": ("cameras", "List the built-in cameras, or show one."),
    "upload": ("upload", "Upload a mission (.plan/.waypoints) to an autopilot and verify it."),
    "download": ("download", "Download the mission stored on an autopilot to a file."),
    "clear": ("clear", "Clear the mission stored on an autopilot."),
    "sim": ("sim", "Run a simulated vehicle (ArduPilot or PX4 flavour) on a MAVLink URL."),
    "monitor": ("monitor", "Record camera triggers and telemetry during a flight."),
    "geotag": ("geotag", "Geotag frames from the flight's own telemetry log."),
    "check": ("check", "Check coverage, overlap, B/H, GSD and blur of images or a plan."),
    "handoff": ("handoff", "Hand the frames to COLMAP, ODM, NodeODM, Metashape or Pix4D; run and measure."),
    "gcp-plan": ("gcp_plan", "Lay out ground control and check points over a planned survey."),
}

#: The group's own text (its docstring in click's terms): paragraphs separated by blank lines.
GROUP_HELP = """sfap: plan drone photo surveys, upload them, geotag the frames and check the coverage
in the field.

Example: sfap plan missions/bardenas-gully.toml -o out/gully"""

#: The group's options as click lists them: (the option's names joined, its help).
VERSION_HELP = "Show the version and exit."
VERBOSE_HELP = "More log output on stderr (-vv for debug)."
QUIET_HELP = "Only errors on stderr."
HELP_HELP = "Show this message and exit."
HELP_OPTION_NAMES = ["-h", "--help"]
GROUP_OPTIONS: tuple[tuple[str, str], ...] = (
    ("--version", VERSION_HELP),
    ("-v, --verbose", VERBOSE_HELP),
    ("-q, --quiet", QUIET_HELP),
    (", ".join(HELP_OPTION_NAMES), HELP_HELP),
)


def help_width() -> int:
    """click's own help width (the terminal's columns, at most 80, less 2, at least 50), found
    without importing shutil: click imports it for this, with zlib, bz2 and lzma."""
    columns = 80
    try:
        columns = int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        try:
            if sys.__stdout__ is not None:
                columns = os.get_terminal_size(sys.__stdout__.fileno()).columns
        except (OSError, ValueError):
            pass
    return max(min(columns, 80) - 2, 50)


def _fill(text: str, width: int, first: str = "", rest: str = "") -> str:
    """One paragraph wrapped as click.formatting.wrap_text does (textwrap, whitespace kept)."""
    import textwrap

    wrapper = textwrap.TextWrapper(
        width, initial_indent=first, subsequent_indent=rest, replace_whitespace=False
    )
    return wrapper.fill(text.expandtabs())


def _paragraphs(text: str, width: int, indent: str) -> str:
    """Paragraphs (separated by blank lines, each re-flowed) wrapped at ``width`` with ``indent``."""
    blocks = [" ".join(line.strip() for line in block.splitlines()) for block in text.split("\n\n")]
    return "\n\n".join(_fill(block, width, indent, indent) for block in blocks if block.strip())


def _definitions(rows: tuple[tuple[str, str], ...], width: int, indent: int) -> list[str]:
    """click's definition list (HelpFormatter.write_dl: first column at most 30, two spaces)."""
    first_col = min(max(len(term) for term, _ in rows), 30) + 2
    text_width = max(width - first_col - 2, 10)
    lines = []
    for term, text in rows:
        head = " " * indent + term
        wrapped = _paragraphs(text, text_width, "").splitlines()
        if len(term) <= first_col - 2:
            head += " " * (first_col - len(term))
        else:
            lines.append(head)
            head = " " * (first_col + indent)
        lines.append(head + wrapped[0])
        lines.extend(" " * (first_col + indent) + line for line in wrapped[1:])
    return lines


def render(prog: str, width: int) -> str:
    """The whole `sfap --help` page for program name ``prog`` at help width ``width``, ending in
    a newline, as click writes it."""
    usage_prefix = f"Usage: {prog} "
    if width >= len(usage_prefix) + 20:
        usage = _fill("[OPTIONS] COMMAND [ARGS]...", width, usage_prefix, " " * len(usage_prefix))
    else:
        usage = usage_prefix + "\n" + _fill("[OPTIONS] COMMAND [ARGS]...", width, " " * 11, " " * 11)
    lines = [usage, "", _paragraphs(GROUP_HELP, width, "  "), "", "Options:"]
    lines += _definitions(GROUP_OPTIONS, width, 2)
    lines += ["", "Commands:"]
    lines += _definitions(tuple((name, text) for name, (_, text) in COMMANDS.items()), width, 2)
    return "\n".join(lines) + "\n"
