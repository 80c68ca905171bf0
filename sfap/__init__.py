"""sfap: small-format aerial photography for drone survey crews (the CLI shell)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("sfap")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
