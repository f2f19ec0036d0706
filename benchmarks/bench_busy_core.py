"""A busy core must not multiply fusionkit's time. The quickstart (ARAS-CAM self-calibration:
Monte-Carlo initializer with 5000 particles over 750 poses, batch LM, marginals) is estimated
in-process with the machine idle and while another process keeps one core busy, each with
fusionkit's one BLAS thread (fusionkit.threads, as shipped) and with numpy's default BLAS threads
(the limit switched off for this benchmark only). The ratio busy / idle is what a loaded laptop
costs; before the limit, a 2-core machine saw 0.9 s -> 24 s in the Monte-Carlo initializer."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import statistics
import time
from pathlib import Path
from unittest import mock

import fusionkit
import fusionkit.pipeline

from _timing import ratio, table

QUICKSTART = Path(__file__).resolve().parent.parent / "configs" / "quickstart.yaml"


def _spin() -> None:
    while True:
        pass


@contextlib.contextmanager
def busy_core():
    """Another process keeping one core busy for the duration of the block."""
    hog = multiprocessing.get_context("spawn").Process(target=_spin, daemon=True)
    hog.start()
    try:
        time.sleep(0.2)
        yield
    finally:
        hog.terminate()
        hog.join()


def _estimate_seconds(config, blas_limit: bool) -> tuple[float, float]:
    """(whole estimate, Monte-Carlo initializer) seconds of one run."""
    switch = contextlib.nullcontext() if blas_limit else \
        mock.patch.object(fusionkit.pipeline, "one_blas_thread", contextlib.nullcontext)
    with switch:
        tic = time.perf_counter()
        result = fusionkit.pipeline.estimate(config)
        total = time.perf_counter() - tic
    mc = next(v for k, v in result.problem.diagnostics.items() if "monte_carlo" in k)["seconds"]
    return total, mc


def run(quick: bool) -> dict:
    repeat = 1 if quick else 3
    config = fusionkit.load_config(QUICKSTART)
    _estimate_seconds(config, True)  # warm-up: imports, caches
    raw: dict[str, dict[str, float]] = {}
    for label, limit in (("one BLAS thread (shipped)", True), ("numpy default BLAS threads", False)):
        samples = {"idle": [], "busy": []}
        for _ in range(repeat):  # interleaved, so slow drifts of the machine hit both alike
            samples["idle"].append(_estimate_seconds(config, limit))
            with busy_core():
                samples["busy"].append(_estimate_seconds(config, limit))
        raw[label] = {f"{state}_{part}": statistics.median(s[i] for s in runs)
                      for state, runs in samples.items() for i, part in enumerate(("total", "mc"))}
    rows = [[label, f"{r['idle_mc']:.2f}", f"{r['busy_mc']:.2f}", ratio(r["busy_mc"], r["idle_mc"]),
             f"{r['idle_total']:.2f}", f"{r['busy_total']:.2f}", ratio(r["busy_total"], r["idle_total"])]
            for label, r in raw.items()]
    text = table(["quickstart estimate", "MC idle s", "MC busy s", "MC busy/idle", "total idle s",
                  "total busy s", "total busy/idle"], rows,
                 f"(busy core) one other process spinning on one of {os.cpu_count()} cores; median of {repeat}")
    return {"text": text, "raw": raw}


def summary(res: dict) -> list[str]:
    shipped, default = res["raw"]["one BLAS thread (shipped)"], res["raw"]["numpy default BLAS threads"]
    return [f"busy core: quickstart estimate busy/idle {ratio(shipped['busy_total'], shipped['idle_total'])} with "
            f"one BLAS thread, {ratio(default['busy_total'], default['idle_total'])} with numpy's default threads "
            f"(Monte-Carlo {ratio(shipped['busy_mc'], shipped['idle_mc'])} vs "
            f"{ratio(default['busy_mc'], default['idle_mc'])})"]


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
