"""Where the small external validation datasets live: `$FUSIONKIT_SHARED_DATA/<name>`, by default
`../shared/data/<name>` beside the repository. Never committed; tests and benchmarks that need
them skip with this path in their reason when the folder is absent."""

from __future__ import annotations

import os
from pathlib import Path

ENV = "FUSIONKIT_SHARED_DATA"
DEFAULT = Path(__file__).resolve().parents[1].parent / "shared" / "data"  # research/ -> repo/..


def external_data(name: str) -> Path:
    """The folder of dataset `name` (it may not exist)."""
    return Path(os.environ.get(ENV, DEFAULT)) / name


def missing_reason(name: str, what: str) -> str:
    """The skip reason when `external_data(name)` is absent."""
    return f"{what} not found at {external_data(name)} (../shared/data/{name}; set {ENV} to its parent)"
