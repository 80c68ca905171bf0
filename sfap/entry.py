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

        sys.stdout.write(render(os.path.basename(sys.argv[0]), help_width()))
        sys.stdout.flush()
        return
    from .cli import cli

    cli()
