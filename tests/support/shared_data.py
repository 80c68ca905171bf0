"""Where the project's shared real data lives: ../shared/data beside the repository (CI puts
it there too), or $SFAP_SHARED_DATA."""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHARED_DATA = Path(os.environ.get("SFAP_SHARED_DATA", REPO.parent / "shared" / "data"))
