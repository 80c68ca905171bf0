"""The sfap command line: a click group whose subcommands live one per module in
``sfap/commands`` and are imported only when run (pymavlink and rasterio are slow to import).

Errors are mapped to exit codes here and nowhere else: 0 success, 1 the operation failed or a
check found problems (a typed error, or a result that reports problems: frames geotag left
untagged), 2 usage (bad options or bad input files).
"""

from __future__ import annotations

import gc
import importlib
import os
import sys
from typing import Any, Protocol, runtime_checkable

import click

from planner.errors import SfapError

from .help_page import (
    COMMANDS,
    GROUP_HELP,
    HELP_OPTION_NAMES,
    QUIET_HELP,
    VERBOSE_HELP,
    VERSION_HELP,
    help_width,
)

#: Commands whose arrays are small (a plan's stations, a camera table, a flight's track, a
#: mission's items): numpy's OpenBLAS is loaded with one thread for them. With one per core it
#: starts the others as numpy is imported, and they spin waiting for work none of these commands
#: gives them: 40 ms of CPU and 40-60 ms of wall time of a small plan
#: (benchmarks/plan_vs_flightplan.py). A value the user set is kept.
ONE_BLAS_THREAD = frozenset({"plan", "gcp-plan", "cameras", "geotag", "upload", "download", "clear"})


@runtime_checkable
class Verdict(Protocol):
    """What a command that judges returns (``sfap check``: a CheckResult; ``sfap geotag``: a
    GeotagResult, passed when every frame was tagged; ``sfap handoff``: a HandoffResult, passed
    unless --run found a block that does not reconstruct): exit 1 unless it passed, after the
    command has presented what it found."""

    passed: bool


def _debug_detail() -> None:
    """The traceback of the error being handled, at debug level (shown with -vv)."""
    import logging  # not at import: `sfap --help` does without it

    logging.getLogger("sfap").debug("error detail", exc_info=True)


class _Context(click.Context):
    def make_formatter(self) -> click.HelpFormatter:
        from click import formatting

        width = self.terminal_width or formatting.FORCED_WIDTH or help_width()
        return self.formatter_class(width=width, max_width=self.max_content_width)


class LazyGroup(click.Group):
    """A group whose commands are imported on first use."""

    context_class = _Context

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module_name, _ = COMMANDS[cmd_name]
        if cmd_name in ONE_BLAS_THREAD and "numpy" not in sys.modules:
            os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        # The imports make objects that live as long as the process and little garbage: the
        # collector, run every 700 allocations, would walk them again and again for nothing
        # (10-25 ms of CPU of `sfap plan`'s imports). Off while they run; then what they made
        # is put out of its sight for good, so that no later full collection walks every
        # module's objects either (20-40 ms of a geotag run).
        collecting = gc.isenabled()
        gc.disable()
        try:
            module = importlib.import_module(f"sfap.commands.{module_name}")
        finally:
            gc.freeze()
            if collecting:
                gc.enable()
        command: click.Command = module.command
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        # Short help from the table, so `sfap --help` imports no command module.
        with formatter.section("Commands"):
            formatter.write_dl([(name, text) for name, (_, text) in COMMANDS.items()])

    def invoke(self, ctx: click.Context) -> Any:
        try:
            result = super().invoke(ctx)
        except SfapError as error:
            _debug_detail()
            click.echo(f"error: {error}", err=True)
            ctx.exit(error.exit_code)
        except OSError as error:
            # A file that cannot be read or written: name it, no traceback.
            _debug_detail()
            where = f" ({error.filename})" if getattr(error, "filename", None) else ""
            click.echo(f"error: {error.strerror or error}{where}", err=True)
            ctx.exit(1)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            ctx.exit(130)
        if isinstance(result, Verdict) and not result.passed:
            ctx.exit(1)  # the command presented the problems it found
        return result


def _print_version(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from . import __version__  # importlib.metadata: only when asked

    click.echo(f"sfap, version {__version__}")
    ctx.exit()


@click.group(
    cls=LazyGroup,
    help=GROUP_HELP,
    context_settings={"help_option_names": HELP_OPTION_NAMES},
)
@click.option(
    "--version",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_print_version,
    help=VERSION_HELP,
)
@click.option("-v", "--verbose", count=True, help=VERBOSE_HELP)
@click.option("-q", "--quiet", is_flag=True, help=QUIET_HELP)
def cli(verbose: int, quiet: bool) -> None:
    """The group: sets up logging for the command that runs (its text: help_page.GROUP_HELP)."""
    import logging

    level = logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)


def main() -> None:
    """The click group itself, for callers that want it (the console script is sfap.entry.main)."""
    cli()
