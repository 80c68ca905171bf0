"""sfap: small-format aerial photography for drone survey crews (the CLI shell).

``sfap.__version__`` is looked up on first use: importlib.metadata costs about as much as the
rest of ``sfap --help`` together, and only ``sfap --version`` needs it.
"""

from typing import Any


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("sfap")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "0.0.0+unknown"


def __getattr__(name: str) -> Any:
    if name == "__version__":
        value = _version()
        globals()["__version__"] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
