"""Test-suite configuration. This file's presence puts tests/ on sys.path, so test modules
can import shared helpers such as ``shared_data``."""

from __future__ import annotations

from shared_data import SHARED_DATA


def pytest_report_header() -> str:
    return f"shared data: {SHARED_DATA}"
