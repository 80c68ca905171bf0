"""The `sfap` program's entry point (pyproject's console script), standard library only.

`sfap --help` and `sfap -h` alone, the page a new user asks for first, are written by
sfap/help_page.py without importing click (most of the command's start-up); everything else
goes to the click group in sfap/cli.py.
"""

from __future__ import annotations

import os
import sys


def main() -> None:
    if sys.argv[1:] in (["--help"], ["-h"]) and "_SFAP_COMPLETE" not in os.environ:
        from .help_page import help_width, render

        sys.stdout.write(render(_program_name(), help_width()))
        sys.stdout.flush()
        return
    from .cli import cli

    try:
        cli()  # click's standalone mode: always ends in SystemExit
    except SystemExit as done:
        exit_at_once(done)
        raise


def _program_name() -> str:
    """The name the help page gives the program: as click names it (``python -m sfap`` when run
    as a module, else the script's file name)."""
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    if spec is not None and spec.name == "sfap.__main__":
        return f"{os.path.basename(sys.executable)} -m sfap"
    return os.path.basename(sys.argv[0])


def exit_at_once(done: SystemExit) -> None:
    """End the process now with ``done``'s status, without the interpreter's teardown; return
    (the caller then exits as usual) when that would not be the same exit.

    A command's work is over when it returns: its files are written and closed (atomically),
    its children reaped. What is left is the interpreter freeing every module and object one by
    one: 50-60 ms after `sfap plan` (numpy, shapely, pyproj, the planner and the plan), more
    than the planning of a small area takes. Skipping it changes nothing the user can see as
    long as the rest of a normal exit happens here: the exit functions run (atexit: logging's
    handlers flushed and closed, weakref finalizers such as temporary folders' clean-up) and
    standard output and error are flushed. It is not done when another thread still runs (a
    normal exit waits for it), nor when the status is a message to print, nor when standard
    output cannot be flushed (a closed pipe: Python's own exit reports it)."""
    code = done.code
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:
        return
    threading = sys.modules.get("threading")
    if threading is not None and threading.active_count() != 1:
        return
    if not _flushed():
        return
    import atexit

    atexit._run_exitfuncs()  # each handler once: they are cleared, a normal exit would find none
    _flushed()
    os._exit(status)


def _flushed() -> bool:
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):
        return False
    return True
