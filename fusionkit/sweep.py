"""`fusionkit sweep SWEEP.yaml`: many runs of one base config -- seeds, `--set`-style overrides on a grid or
a list, data folders -- on a local process pool or a Ray cluster, gathered into one table.

    config: configs/quickstart.yaml          # the base config (relative to this file)
    seeds: [0, 1, 2]                         # optional: added to every `simulate` source's own seed
    grid:                                    # optional: every combination of these overrides
      sources.0.params.pulley_error: [0.02, 0.05]
    runs:                                    # optional: listed override sets (each combined with the grid)
      - {sources.0.params.duration: 10}
    figures:                                 # key paths into report.json, one column each
      - evaluation.trajectories.cdpr.ate_rmse_m
      - evaluation.parameters.cdpr.pulley.mean_abs_error

One run is one task; a worker receives the config's path and the override text, never GTSAM objects,
and returns its figures (a failed run returns its one-line error: reported, not fatal). With `--out`,
`sweep.csv` (one row per run), `summary.txt` (mean, standard deviation and count of each figure per
setting, over the seeds) and `plots/<figure>.png` (each figure against each numeric swept key) are
written with the rules of `run --out`.
"""

from __future__ import annotations

import argparse
import csv
import io
import itertools
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from .hookspecs import hookimpl
from .components import Command
from .config.yamlio import load_yaml
from .config.schema import validate_against
from .errors import FusionkitError
from .parallel import BACKENDS, run_tasks

SCHEMA = {"type": "object",
          "properties": {"config": {"type": "string"},
                         "seeds": {"type": "array", "items": {"type": "integer"}, "minItems": 1},
                         "grid": {"type": "object", "minProperties": 1,
                                  "additionalProperties": {"type": "array", "minItems": 1}},
                         "runs": {"type": "array", "minItems": 1, "items": {"type": "object"}},
                         "figures": {"type": "array", "minItems": 1, "items": {"type": "string"}}},
          "required": ["config", "figures"], "additionalProperties": False}


def run_settings(sweep: dict, simulate_sources: dict[int, int]) -> list[dict[str, Any]]:
    """Every run's overrides {key path: value}: the listed runs times the grid times the seeds (a sweep seed
    is added to each `simulate` source's own seed, {source index: its seed}, so sources stay distinct)."""
    grid = sweep.get("grid", {})
    points = [dict(zip(grid, values)) for values in itertools.product(*grid.values())] if grid else [{}]
    listed = sweep.get("runs", [{}])
    seeds = [{f"sources.{i}.seed": base + seed for i, base in simulate_sources.items()} for seed in sweep["seeds"]] \
        if "seeds" in sweep else [{}]
    return [{**run, **point, **seed} for run in listed for point in points for seed in seeds]


def figure(document: dict, path: str) -> Any:
    """The value at a dot-separated key path of report.json (list elements by index); None if absent."""
    node: Any = document
    for part in path.split("."):
        if isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return None
    return node


def override_text(value: Any) -> str:
    """A value as the text of a `--set` assignment that reads back as the same value: JSON (a subset of
    YAML) quotes every string, so '1e-3' stays a string; floats that JSON cannot write as YAML's."""
    if isinstance(value, float) and not np.isfinite(value):
        return ".nan" if np.isnan(value) else (".inf" if value > 0 else "-.inf")
    return json.dumps(value)


def run_one(config: str, overrides: dict[str, Any], figures: list[str]) -> dict[str, Any]:
    """One run (in a worker): {status, seconds, figures..., error}."""
    from .config.loader import load_config
    from .pipeline import estimate
    from .report.outputs import report_document
    from .threads import one_blas_thread
    tic = time.perf_counter()
    assignments = [f"{key}={override_text(value)}" for key, value in overrides.items()]
    try:
        with one_blas_thread():
            result = estimate(load_config(config, assignments), keep_rejected=True)
        document = report_document(result)
        out = {"status": document["status"], **{f: figure(document, f) for f in figures}}
    except FusionkitError as exc:
        out = {"status": "error", "error": str(exc).splitlines()[0], **{f: None for f in figures}}
    except Exception as exc:  # a bug in one run must not take the sweep's other runs with it
        out = {"status": "error", "error": f"internal error: {type(exc).__name__}: {exc}".splitlines()[0],
               **{f: None for f in figures}}
    out["seconds"] = time.perf_counter() - tic
    return out


def execute(config: str, settings: list[dict], figures: list[str], backend: str, workers: int) -> list[dict]:
    """Every run's results, in the order of `settings`, on a local process pool or Ray."""
    return run_tasks(run_one, [(config, s, figures) for s in settings], backend, workers)


def _cell(value: Any) -> Any:
    """A figure in the CSV: numbers and text as they are, lists and mappings as JSON, absent as empty."""
    if value is None:
        return ""
    return json.dumps(value) if isinstance(value, (list, dict)) else value


def table_text(settings: list[dict], results: list[dict], figures: list[str]) -> str:
    keys = list(dict.fromkeys(k for s in settings for k in s))
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["run", *keys, "status", "seconds", *figures, "error"])
    for i, (s, r) in enumerate(zip(settings, results)):
        writer.writerow([i, *[s.get(k, "") for k in keys], r["status"], f"{r['seconds']:.3f}",
                         *[_cell(r[f]) for f in figures], r.get("error", "")])
    return buffer.getvalue()


def summary_text(settings: list[dict], results: list[dict], figures: list[str]) -> str:
    """Per setting (the overrides other than seeds): each figure's mean, standard deviation and count."""
    groups: dict[tuple, list[dict]] = {}
    for s, r in zip(settings, results):
        key = tuple((k, repr(v)) for k, v in s.items() if not k.endswith(".seed"))
        groups.setdefault(key, []).append(r)
    lines = [f"{f}: absent from every run's report.json (check the key path)" for f in figures
             if all(r[f] is None for r in results if r["status"] != "error")]
    lines += [f"{f}: not a number (in sweep.csv as JSON; no mean)" for f in figures
              if any(isinstance(r[f], (list, dict, str)) for r in results)]
    for key, runs in groups.items():
        head = ", ".join(f"{k}={v}" for k, v in key) or "base config"
        failed = sum(r["status"] == "error" for r in runs)
        rejected = sum(r["status"] == "rejected" for r in runs)
        lines.append(f"{head}: {len(runs)} run(s)" + (f", {failed} failed" if failed else "")
                     + (f", {rejected} rejected by a check (counted below)" if rejected else ""))
        for f in figures:
            values = np.array([r[f] for r in runs if isinstance(r[f], (int, float)) and not isinstance(r[f], bool)],
                              float)
            if len(values):
                lines.append(f"  {f}: mean {values.mean():.6g}, std {values.std(ddof=1) if len(values) > 1 else 0.0:.3g}"
                             f" (n = {len(values)})")
    return "\n".join(lines) + "\n"


def plots(settings: list[dict], results: list[dict], figures: list[str]) -> dict[str, bytes]:
    """plots/<figure>.png: each figure against each swept key whose values are numbers (mean and spread)."""
    swept = [k for k in dict.fromkeys(k for s in settings for k in s) if not k.endswith(".seed")
             and all(isinstance(s.get(k), (int, float)) for s in settings)]
    if not swept:
        return {}
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = {}
    for f in figures:
        fig, axes = plt.subplots(1, len(swept), figsize=(4.5 * len(swept), 3.5), squeeze=False)
        for ax, key in zip(axes[0], swept):
            xs = sorted({s[key] for s in settings})
            values = [[r[f] for s, r in zip(settings, results) if s[key] == x and isinstance(r[f], (int, float))]
                      for x in xs]
            ax.errorbar(xs, [np.mean(v) if v else np.nan for v in values],
                        yerr=[np.std(v, ddof=1) if len(v) > 1 else 0.0 for v in values], marker="o", capsize=3)
            ax.set_xlabel(key)
            ax.set_ylabel(f)
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=100)
        plt.close(fig)
        out[f"plots/{f.replace('/', '_')}.png"] = buffer.getvalue()
    return out


class Sweep(Command):
    name = "sweep"
    summary = "many runs of one config (seeds, overrides on a grid or a list) on local processes or Ray: one table"

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("sweep", help="the sweep file (YAML)")
        parser.add_argument("--out", help="folder for sweep.csv, summary.txt and plots/")
        parser.add_argument("--backend", choices=BACKENDS, default="local",
                            help="local process pool (default) or a Ray cluster (RAY_ADDRESS, or a local one)")
        parser.add_argument("--workers", type=int, default=2, help="local processes (default 2)")

    def run(self, args: argparse.Namespace) -> int:
        doc = load_yaml(args.sweep)
        validate_against(doc, SCHEMA, doc.data)
        sweep = doc.data
        config = (Path(args.sweep).parent / sweep["config"]).resolve()
        if not config.is_file():
            raise doc.error(("config",), f"config not found: {config}")
        from .config.loader import load_config
        base = load_config(config)  # a base config that does not load is one line before any run
        simulate_sources = {i: int(s["seed"]) for i, s in enumerate(base.sources) if s.type == "simulate"}
        if "seeds" in sweep and not simulate_sources:
            raise doc.error(("seeds",), "seeds set the seed of `simulate` sources; the config has none")
        if args.out:
            from .report.writer import check_output_folder
            check_output_folder(Path(args.out), [Path(args.sweep), config])
        settings = run_settings(sweep, simulate_sources)
        tic = time.perf_counter()
        results = execute(str(config), settings, sweep["figures"], args.backend, args.workers)
        wall = time.perf_counter() - tic
        summary = summary_text(settings, results, sweep["figures"])
        busy = sum(r["seconds"] for r in results)
        print(f"fusionkit sweep: {len(settings)} run(s) on {args.backend} in {wall:.2f} s "
              f"({busy:.2f} s inside the runs), {sum(r['status'] == 'error' for r in results)} failed")
        print(summary, end="")
        for i, r in enumerate(results):
            if r["status"] == "error":
                print(f"  run {i}: {r['error']}")
        if args.out:
            from .report.writer import write_output_folder
            files = {"sweep.csv": table_text(settings, results, sweep["figures"]), "summary.txt": summary,
                     **plots(settings, results, sweep["figures"])}
            write_output_folder(Path(args.out), "sweep", files, [Path(args.sweep), config])
            print(f"  outputs: {args.out}/ (sweep.csv, summary.txt{', plots/' if len(files) > 2 else ''})")
        return 0


@hookimpl
def register_commands():
    return [Sweep]
