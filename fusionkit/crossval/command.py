"""`fusionkit crossval CONFIG`: held-out prediction errors of the config's calibration, per factor entry, in
its measurements' units (docs/cli.md#crossval; the method in fusionkit/crossval/predict.py)."""

from __future__ import annotations

import argparse
import io
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from ..hookspecs import hookimpl
from ..components import Command
from ..errors import ConfigError
from ..parallel import BACKENDS
from .folds import BY, Plan
from .run import Outcome, crossval

SHOWN = {"m": (1e3, "mm"), "rad": (180.0 / np.pi, "deg")}  # console only: crossval.json keeps SI units


def _shown(value: float, unit: str) -> str:
    scale, label = SHOWN.get(unit, (1.0, unit))
    return f"{value * scale:.3g}{(' ' + label) if label else ''}"


def _cuts(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(c) for c in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected times in s separated by commas, e.g. 60.5,121") from None


class CrossVal(Command):
    name = "crossval"
    summary = ("held-out prediction: calibrate on part of the data, predict the rest from the reference streams, "
               "and compare per entry in its units (folds, leave-one-out or a split; local processes or Ray)")

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("config")
        how = parser.add_mutually_exclusive_group(required=True)
        how.add_argument("--folds", type=int, metavar="K", help="K folds: every K-th sample, or K equal stretches "
                         "of time (--by segment)")
        how.add_argument("--leave-one-out", action="store_true", help="each sample (or each --cuts segment) held "
                         "out once")
        how.add_argument("--split", type=float, metavar="FRACTION", help="train on the first FRACTION (0..1) in "
                         "time, predict the rest")
        parser.add_argument("--by", choices=BY, help="what is held out: samples (a static configuration, a frame), "
                            "segments of time, or files (the recordings of a source given several) (default: files "
                            "when there are several recordings, else segments when a factor links consecutive "
                            "states, else samples)")
        parser.add_argument("--cuts", type=_cuts, metavar="T1,T2,...", help="segment boundaries (s), e.g. where "
                            "recordings laid end to end meet; each segment is one fold")
        parser.add_argument("--reference", action="append", metavar="STREAM", help="stream the held-out states "
                            "are solved from (repeatable; default: the streams that clock the robots' states)")
        parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                            help="override a config value, as for run (repeatable)")
        parser.add_argument("--out", help="folder for crossval.json and plots/ (default: out/<config name>-crossval)")
        parser.add_argument("--backend", choices=BACKENDS, default="local",
                            help="local processes (default) or a Ray cluster (RAY_ADDRESS, or a local one)")
        parser.add_argument("--workers", type=int, default=1, help="local processes (default 1: in this one)")

    def run(self, args: argparse.Namespace) -> int:
        from ..config.loader import load_config
        from ..report.writer import check_output_folder, write_output_folder
        config = load_config(args.config, args.set)
        out = Path(args.out) if args.out else Path("out") / f"{config.name}-crossval"
        inputs = [Path(args.config), *config.input_paths()]
        check_output_folder(out, inputs)
        reference = args.reference or sorted({setup.states["stream"] for setup in config.robots.values()
                                              if setup.states and "stream" in setup.states})
        if not reference:
            raise ConfigError("--reference: no robot's states follow a stream; name the streams the held-out "
                              "states are solved from")
        plan = self._plan(args)
        with ProcessPoolExecutor(1) as painter:  # imports matplotlib (a second) while the folds run
            painter.submit(_import_matplotlib)
            outcome = crossval(str(Path(args.config).resolve()), args.set, plan, reference, args.backend, args.workers)
            ran = [f for f in outcome.folds if "error" not in f]
            if not ran:
                raise ConfigError(f"every fold failed; the first: {outcome.folds[0]['error']}")
            plot = painter.submit(folds_plot, outcome.pooled, outcome.folds).result()
        print("\n".join(summary_lines(args.config, outcome)))
        files = {"crossval.json": json.dumps(document(outcome), indent=2)}
        if plot is not None:
            files["plots/folds.png"] = plot
        write_output_folder(out, "crossval", files, inputs)
        print(f"  outputs: {out}/ ({', '.join(sorted({f.split('/')[0] + ('/' if '/' in f else '') for f in files}))})")
        return 0

    @staticmethod
    def _plan(args) -> Plan:
        if args.folds is not None and args.folds < 2:
            raise ConfigError(f"--folds {args.folds}: expected 2 or more")
        if args.split is not None and not 0 < args.split < 1:
            raise ConfigError(f"--split {args.split}: expected a fraction between 0 and 1")
        if args.cuts and args.by in ("sample", "file"):
            raise ConfigError("--cuts: segments only (--by segment)")
        if args.by == "file" and args.split is not None:
            raise ConfigError("--split and --by file: a split is in time (--by segment); by file, each recording is "
                              "held out once (--leave-one-out)")
        if args.cuts and args.split is not None:
            raise ConfigError("--cuts and --split: give one of them (a split is one cut)")
        by = "segment" if args.cuts else args.by or "auto"
        return Plan(by, args.folds, args.leave_one_out, args.split, args.cuts or ())


def summary_lines(config: str, outcome: Outcome) -> list[str]:
    ran = [f for f in outcome.folds if "error" not in f]
    failed = [f for f in outcome.folds if "error" in f]
    rejected = [f for f in ran if f["training"]["status"] == "rejected"]
    lines = [f"crossval {config}: {outcome.plan.describe()}, reference {', '.join(outcome.reference)}: "
             f"{len(ran)} of {len(outcome.folds)} fits ran" + (f", {len(failed)} failed" if failed else "")
             + f" ({outcome.seconds:.2f} s)"]
    rows = [("held-out prediction", "RMSE", "largest", "model predicts", "fold spread", "e'S^-1e/dim")]
    for label, entry in outcome.pooled.items():
        for name, p in entry["parts"].items():
            chi = f"{entry['chi2_per_dim']:.2f}" if entry["chi2_per_dim"] is not None else "-"
            rows.append((f"{label} {name} (n = {p['count']})",
                         *(_shown(p[k], p["unit"]) for k in ("rmse", "max", "predicted_rmse", "fold_std")), chi))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines += ["  " + "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
              for r in rows]
    chi2 = [f["training"]["chi2_per_dof"] for f in ran if f["training"]["chi2_per_dof"] is not None]
    if chi2:
        lines.append(f"  training fits: chi2/dof {min(chi2):.3g} .. {max(chi2):.3g}; "
                     + (f"{len(rejected)} rejected by a check (fold(s) {', '.join(str(f['fold']) for f in rejected)})"
                        if rejected else "all accepted"))
    warned: dict[str, int] = {}
    for f in ran:
        for name in dict.fromkeys(w.split(":")[0] for w in f["training"]["warnings"]):
            warned[name] = warned.get(name, 0) + 1
    if warned:
        lines.append("  training warnings (crossval.json has them): " + ", ".join(f"{name} in {n} fold(s)"
                                                                              for name, n in warned.items()))
    anchored = sorted({a for f in ran for a in f["anchored_by"]})
    if anchored:
        lines.append(f"  the reference measures motion only: each held-out stretch starts at the first measurement of "
                     f"{', '.join(anchored)} (not scored)")
    unpredicted = sum(f["unpredicted"] for f in ran)
    if unpredicted:
        lines.append(f"  {unpredicted} held-out measurement(s) not predicted: they read a variable the reference does "
                     "not determine")
    for label, entry in outcome.pooled.items():
        if entry["check"]:
            lines.append(f"  warning [predictive_check] {label}: {entry['check']}")
    for f in failed:
        lines.append(f"  fold {f['fold']} ({', '.join(f['held_out'][:3])}{' ...' if len(f['held_out']) > 3 else ''}): "
                     f"{f['error']}")
    return lines


def document(outcome: Outcome) -> dict:
    checks = {label: entry["check"] for label, entry in outcome.pooled.items() if entry["check"]}
    return {"status": "warning" if checks else "consistent", "plan": outcome.plan.describe(),
            "by": outcome.plan.by, "reference": list(outcome.reference), "seconds": outcome.seconds,
            "pooled": {label: {k: v for k, v in entry.items() if k not in ("chi2", "dim")}
                       for label, entry in outcome.pooled.items()},
            "warnings": [{"name": "predictive_check", "entry": label, "message": m} for label, m in checks.items()],
            "folds": outcome.folds}


def _import_matplotlib() -> None:
    import matplotlib.figure  # noqa: F401


def folds_plot(pooled: dict, folds: list[dict]) -> bytes | None:
    """Each entry part's RMS held-out error per fold (bars), with the RMS the model predicts (line)."""
    panels = [(label, name, p) for label, entry in pooled.items() for name, p in entry["parts"].items()]
    if not panels:
        return None
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(8, 2.6 * len(panels)))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, squeeze=False)
    for ax, (label, name, p) in zip(axes[:, 0], panels):
        scale, unit = SHOWN.get(p["unit"], (1.0, p["unit"]))
        ran = [f for f in folds if label in f.get("entries", {})]
        ax.bar([f["fold"] for f in ran], [f["entries"][label]["parts"][name]["rmse"] * scale for f in ran],
               color="#4c72b0", label="held-out RMSE")
        ax.axhline(p["predicted_rmse"] * scale, color="#dd8452", ls="--", label="model predicts (pooled)")
        ax.set_title(f"{label} {name}", fontsize=9)
        ax.set_xlabel("fold")
        ax.set_ylabel(unit or "stream units")
        ax.legend(fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


@hookimpl
def register_commands():
    return [CrossVal]
