"""Options and presentation shared by the subcommands (defined once, as rasterio's rio does)."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import click

from planner.outputs import json_safe

F = TypeVar("F", bound=Callable[..., Any])

json_option = click.option(
    "--json", "as_json", is_flag=True, help="Print the result as JSON on stdout instead of a table."
)
overwrite_option = click.option(
    "--overwrite", is_flag=True, help="Replace existing output files (off: refuse and keep them)."
)


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
