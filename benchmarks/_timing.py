"""Tiny shared helpers: median wall time with time.perf_counter, and a plain-text table."""

from __future__ import annotations

import gc
import statistics
import time
from typing import Any, Callable

import numpy as np


def timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    """(result, seconds) of one call."""
    tic = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - tic


def median_time(fn: Callable[[], Any], repeat: int = 5, warmup: int = 1) -> float:
    """Median seconds of `repeat` calls of fn() after `warmup` untimed calls (GC off while timing)."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeat):
        gc.collect()
        gc.disable()
        try:
            tic = time.perf_counter()
            fn()
            samples.append(time.perf_counter() - tic)
        finally:
            gc.enable()
    return statistics.median(samples)


def latency_percentiles(latency: np.ndarray) -> dict[str, float]:
    """p50, p90, p99 and max of per-step latencies (in their unit), and how many steps."""
    return {"steps": len(latency), "p50": float(np.percentile(latency, 50)), "p90": float(np.percentile(latency, 90)),
            "p99": float(np.percentile(latency, 99)), "max": float(latency.max())}


def median_of(runs: list[dict[str, float]]) -> dict[str, float]:
    """Per-key median over several runs' timing dicts."""
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def table(headers: list[str], rows: list[list[Any]], title: str = "") -> str:
    """Right-aligned columns (first column left-aligned); floats are formatted by the caller."""
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]

    def line(r):
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))

    out = []
    if title:
        out += [title, "=" * len(title)]
    out += [line(headers), line(["-" * w for w in widths])]
    out += [line(r) for r in cells]
    return "\n".join(out)


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:.1f}"


def us(seconds: float) -> str:
    return f"{seconds * 1e6:.2f}"


def ratio(a: float, b: float) -> str:
    return f"{a / b:.2f}x" if b > 0 else "n/a"


def with_big_stack(fn: Callable[[], Any], megabytes: int = 1024) -> Any:
    """Run fn() in a thread with a large stack and return its result (re-raising its exception).

    GTSAM's recursive Bayes-tree code overflows the default 8 MB main-thread stack on long pose
    chains (the 100k-state LM solve segfaults with `ulimit -s 8192`); untouched stack pages cost
    no memory."""
    import threading
    out: dict[str, Any] = {}

    def target():
        try:
            out["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller
            out["error"] = exc

    old = threading.stack_size(megabytes * 1024 * 1024)
    try:
        t = threading.Thread(target=target, name="bench")
        t.start()
    finally:
        threading.stack_size(old)
    t.join()
    if "error" in out:
        raise out["error"]
    return out["value"]


def run_parts(parts: dict[str, Callable[[], tuple[str, dict]]]) -> dict:
    """Run a section's parts in order, each returning (table text, raw numbers): the section's
    {"text": the tables, "raw": {part: numbers}}."""
    texts, raw = [], {}
    for name, part in parts.items():
        text, raw[name] = part()
        texts.append(text)
    return {"text": "\n\n".join(texts), "raw": raw}


def section_main(doc: str, run: Callable[[bool], dict], summary: Callable[[dict], list[str]] | None = None) -> None:
    """The command line of one benchmark section: `python bench_x.py [--quick]` runs it (in a
    thread with a big stack, as run_all.py does) and prints its tables, then its summary lines."""
    import argparse
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smaller sizes and fewer repeats")
    quick = ap.parse_args().quick
    res = with_big_stack(lambda: run(quick))
    print(res["text"])
    if summary:
        print("\n".join(summary(res)))
