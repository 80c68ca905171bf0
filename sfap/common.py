"""Options and presentation shared by the subcommands (defined once, as rasterio's rio does)."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import click

from planner.outputs import json_safe


class FiniteFloatRange(click.FloatRange):
    """click's FloatRange refusing NaN and infinities too (FloatRange lets NaN through: every
    comparison with NaN is false), so a timeout of nan never means waiting forever."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = click.FLOAT.convert(value, param, ctx)
        if number != number or number in (float("inf"), float("-inf")):
            self.fail(f"{value} is not a finite number", param, ctx)
        return super().convert(number, param, ctx)


class FiniteFloat(click.types.FloatParamType):
    """click's float refusing NaN and infinities (``float("nan")`` parses, and every comparison with
    it is false, so a check of the value downstream would let it through)."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = super().convert(value, param, ctx)
        if number != number or number in (float("inf"), float("-inf")):
            self.fail(f"{value} is not a finite number", param, ctx)
        return number


#: The type of every float option without bounds.
FINITE_FLOAT = FiniteFloat()

F = TypeVar("F", bound=Callable[..., Any])

json_option = click.option(
    "--json", "as_json", is_flag=True, help="Print the result as JSON on stdout instead of a table."
)
overwrite_option = click.option(
    "--overwrite", is_flag=True, help="Replace existing output files (off: refuse and keep them)."
)


def connect_options(function: F) -> F:
    """The options of every command that talks to a vehicle, defined once: --connect (the URL
    carries a serial port's baud rate), --signing-key, --require-signing (MAVLink 2 signing)
    and --heartbeat-timeout-s."""
    from acquisition.signing import SIGNING_KEY_ENV  # here: only vehicle commands import pymavlink

    options = (
        click.option(
            "--connect",
            "url",
            required=True,
            metavar="URL",
            help=(
                "How to reach the vehicle: serial:///dev/ttyUSB0:57600 (device:baud), "
                "udpin://0.0.0.0:14550, udpout://HOST:PORT, tcp://HOST:PORT or tcpin://HOST:PORT."
            ),
        ),
        click.option(
            "--signing-key",
            "signing_key_file",
            type=click.Path(dir_okay=False, path_type=Path),
            default=None,
            help=(
                "MAVLink 2 signing key file: 32 raw bytes, 64 hex digits, or a passphrase "
                f"(SHA-256, as MAVProxy). Default: ${SIGNING_KEY_ENV} if set, else no signing."
            ),
        ),
        click.option(
            "--require-signing",
            is_flag=True,
            help="Refuse unsigned messages from the vehicle (needs a key).",
        ),
        click.option(
            "--heartbeat-timeout-s",
            type=FiniteFloatRange(min=0.1),
            default=10.0,
            show_default=True,
            help="Seconds to wait for the vehicle's heartbeat when connecting.",
        ),
    )
    for option in reversed(options):
        function = option(function)
    return function


def dumps_json(data: Any) -> str:
    return json.dumps(json_safe(data), indent=2, allow_nan=False)


def echo_json(data: Any) -> None:
    click.echo(dumps_json(data))


def echo_table(rows: list[tuple[str, str]], title: str | None = None) -> None:
    """Two columns, key and value, aligned."""
    if title:
        click.echo(title)
    width = max((len(k) for k, _ in rows), default=0)
    for key, value in rows:
        click.echo(f"  {key.ljust(width)}  {value}")


@contextmanager
def progress(label: str, total: int, enabled: bool = True) -> Iterator[Callable[[int], None]]:
    """A progress bar on stderr; yields ``advance(n)`` for library callbacks."""
    stream = sys.stderr
    if not enabled or total <= 0 or not stream.isatty():
        yield lambda n: None
        return
    with click.progressbar(length=total, label=label, file=stream) as bar:
        yield bar.update


@contextmanager
def warnings_once(*prefixes: str) -> Iterator[set[str]]:
    """Print each warning once. A command that lists its result's warnings in its summary adds
    them to the yielded set (and those it leaves out on purpose); what the loggers under
    ``prefixes`` (package names) warn of meanwhile is held back from the log handlers that write
    to stderr, and whatever of it is not in the set is printed when the command ends (also on an
    error), in order, once."""
    import logging

    held: list[str] = []
    handled: set[str] = set()
    dotted = tuple(prefix + "." for prefix in prefixes)

    def hold(record: logging.LogRecord) -> bool:
        if record.levelno == logging.WARNING and (record.name + ".").startswith(dotted):
            held.append(record.getMessage())
            return False
        return True

    handlers = [h for h in logging.getLogger().handlers if getattr(h, "stream", None) is sys.stderr]
    for handler in handlers:
        handler.addFilter(hold)
    try:
        yield handled
    finally:
        for handler in handlers:
            handler.removeFilter(hold)
        for message in dict.fromkeys(held):
            if message not in handled:
                click.echo(f"warning: {message}", err=True)
