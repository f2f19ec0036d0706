"""Progress of long work: the pipeline names each stage (reading, building, initializing, solving,
covariances) and solvers report iterations; the command line shows them as one transient status
line on stderr (rich), library callers pass nothing and see nothing."""

from __future__ import annotations

import math
import threading
from typing import Protocol

from rich.console import Console

SHOW_AFTER_S = 1.0  # work shorter than this never shows a status line


class StatusLine:
    """A context manager; inside it `stage(text)` names the current work and calling it with
    (iteration, cost) adds the solver's progress to that line. It appears once the work has taken
    SHOW_AFTER_S and is erased when the context ends."""

    def __init__(self, console: Console | None = None) -> None:
        self._status = (console or Console(stderr=True)).status("")
        self._text = ""
        self._stage = ""
        self._timer = threading.Timer(SHOW_AFTER_S, self._begin)
        self._timer.daemon = True
        self._started = self._closed = False
        self._lock = threading.Lock()

    def __enter__(self) -> "StatusLine":
        self._timer.start()
        return self

    def __exit__(self, *exc) -> None:
        self._timer.cancel()
        with self._lock:
            if self._started:
                self._status.stop()
            self._closed = True

    def _begin(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._status.update(self._text)
            self._status.start()
            self._started = True

    def _show(self, text: str) -> None:
        with self._lock:
            self._text = text
            if self._started:
                self._status.update(text)

    def stage(self, text: str) -> None:
        self._stage = text
        self._show(text)

    def __call__(self, iteration: int, cost: float) -> None:
        cost_text = "" if math.isnan(cost) else f", cost {cost:.6g}"
        self._show(f"{self._stage}: iteration {iteration}{cost_text}")


class Progress(Protocol):
    """What long work reports to: `stage(text)` names the work, `(iteration, cost)` counts it."""

    def stage(self, text: str) -> None: ...

    def __call__(self, iteration: int, cost: float) -> None: ...
