"""Atomic output: everything is written to a temporary folder that replaces DIR only on success."""

from __future__ import annotations

import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import FusionkitError


@contextmanager
def atomic_directory(out: Path) -> Iterator[Path]:
    """Yield a fresh folder beside `out`; on success it becomes `out`, on error it vanishes."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FusionkitError(f"{out}: exists and is not a folder; choose another output folder")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
