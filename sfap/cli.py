"""The sfap command line: a click group whose subcommands live one per module in
``sfap/commands`` and are imported only when run (pymavlink and rasterio are slow to import).

Errors are mapped to exit codes here and nowhere else: 0 success, 1 the operation failed or a
check found problems, 2 usage (bad options or bad input files).
"""

from __future__ import annotations

import importlib
import logging
import sys
from typing import Any

import click

from planner.errors import SfapError

from . import __version__

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
    "gcp-plan": ("gcp_plan", "Lay out ground control and check points over a planned survey."),
}

log = logging.getLogger("sfap")


class LazyGroup(click.Group):
    """A group whose commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module_name, _ = COMMANDS[cmd_name]
        module = importlib.import_module(f"sfap.commands.{module_name}")
        command: click.Command = module.command
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        # Short help from the table, so `sfap --help` imports no command module.
        with formatter.section("Commands"):
            formatter.write_dl([(name, text) for name, (_, text) in COMMANDS.items()])

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except SfapError as error:
            log.debug("error detail", exc_info=True)
            click.echo(f"error: {error}", err=True)
            ctx.exit(error.exit_code)
        except OSError as error:
            # A file that cannot be read or written: name it, no traceback.
            log.debug("error detail", exc_info=True)
            where = f" ({error.filename})" if getattr(error, "filename", None) else ""
            click.echo(f"error: {error.strerror or error}{where}", err=True)
            ctx.exit(1)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            ctx.exit(130)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="sfap")
@click.option("-v", "--verbose", count=True, help="More log output on stderr (-vv for debug).")
@click.option("-q", "--quiet", is_flag=True, help="Only errors on stderr.")
def cli(verbose: int, quiet: bool) -> None:
    """sfap: plan drone photo surveys, upload them, geotag the frames and check the coverage
    in the field.

    Example: sfap plan missions/bardenas-gully.toml -o out/gully
    """
    level = logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)


def main() -> None:
    cli()
