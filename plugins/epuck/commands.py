"""`fusionkit epuck-fit-ir` and `fusionkit epuck-fit-motion`: the e-puck's IR sensor models and
velocity-model noise from calibration data (fitting.py; docs/models/epuck.md#fitting-the-models).
Each writes a YAML fragment to paste into an epuck robot description and a JSON report of the fit."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from fusionkit.api import Command, ConfigError, DataError, check_output_folder, read_csv_stream, write_output_folder


def _curve_report(fit) -> dict:
    return {"terms": fit.terms, "chi2": fit.chi2, "dof": fit.dof, "chi2_per_dof": fit.chi2_per_dof,
            "candidates": {str(k): v for k, v in fit.candidates.items()},
            "residual_sigmas": fit.residual_sigmas.round(3).tolist(), "curve_sigma": fit.curve_sigma.tolist()}


def fitting():
    """The fitting module, imported when a command runs (scipy.stats and scipy.optimize take a fifth of a
    second, which every `fusionkit` call would pay when plugins register)."""
    from . import fitting as module
    return module


class FitIr(Command):
    name = "epuck-fit-ir"
    summary = ("e-puck: fit each IR sensor's mean-reading and variance models (Gaussian sums, 1-3 terms by BIC) to "
               "readings at known distances; writes the sensors' models for a robot description")

    def add_arguments(self, parser) -> None:
        parser.add_argument("readings", help="CSV: distance (m, sensor to wall along its axis, 0: touching), sensor "
                            "(index 0..), reading (counts); one row per reading, several per distance; a first "
                            "column t is allowed, not needed")
        parser.add_argument("--out", required=True, help="output folder: ir_models.yaml, fit.json; replaced only "
                            "when it is new, empty or an earlier fusionkit output")
        parser.add_argument("--unit", type=float, default=0.01, metavar="M",
                            help="x unit of the Gaussian sums in m (default 0.01: cm, as published)")
        parser.add_argument("--max-terms", type=int, default=3, choices=(1, 2, 3), help="most terms tried (default 3)")
        parser.add_argument("--names", default="ir{i}", help="sensor name pattern (default ir{i})")

    def run(self, args) -> int:
        if args.unit <= 0:
            raise ConfigError(f"--unit {args.unit}: expected a positive length in m")
        path = Path(args.readings)
        check_output_folder(Path(args.out), [path])
        data = read_csv_stream(path, "readings", ("distance", "sensor", "reading"), indexed=True)
        distance, sensor, reading = (data.column(c) for c in ("distance", "sensor", "reading"))
        if np.any(distance < 0) or np.any(sensor != np.round(sensor)) or np.any(sensor < 0):
            raise DataError(f"{path}: distance must be >= 0 (m) and sensor a non-negative integer on every row")
        models, report = {}, {"unit_m": args.unit, "sensors": {}}
        lines = [f"epuck-fit-ir: {path.name}: {len(reading)} readings at {distance.min():g} .. {distance.max():g} m "
                 f"(ir_range), x unit {args.unit:g} m"]
        for s in np.unique(sensor).astype(int):
            rows = sensor == s
            try:
                fit = fitting().fit_sensor(distance[rows], reading[rows], args.unit, args.max_terms)
            except ValueError as exc:
                raise DataError(f"{path}: sensor {s}: {exc}") from None
            name = args.names.format(i=s)
            models[name] = {"mean": fit.mean_fit.terms, "variance": fit.var_fit.terms}
            report["sensors"][name] = {"dropouts": fit.dropped, "x": fit.x.tolist(), "count": fit.count.tolist(),
                                       "mean": fit.mean.tolist(),
                                       "variance": fit.var.tolist(), "mean_fit": _curve_report(fit.mean_fit),
                                       "variance_fit": _curve_report(fit.var_fit)}
            lines.append(f"  {name}: {len(fit.x)} distances" + (f", {fit.dropped} drop-out(s) (0 mid-range) left "
                                                                 "out" if fit.dropped else "")
                         + f"; mean {len(fit.mean_fit.terms)} term(s), chi2/dof "
                         f"{fit.mean_fit.chi2_per_dof:.2f}; variance {len(fit.var_fit.terms)} term(s), chi2/dof "
                         f"{fit.var_fit.chi2_per_dof:.2f}; worst residual {np.abs(fit.mean_fit.residual_sigmas).max():.1f}"
                         f" / {np.abs(fit.var_fit.residual_sigmas).max():.1f} sigma")
        fitted = [float(distance.min()), float(distance.max())]
        report["ir_range"] = fitted
        text = ("# IR sensor models fitted by fusionkit epuck-fit-ir: merge into an epuck description -- the models "
                "into its `sensors:`, and ir_range, the distances (m) they were fitted on (outside them readings are "
                "censored)\n") + yaml.safe_dump({"ir_distance_unit": args.unit, "ir_range": fitted,
                                                  "sensors": models}, sort_keys=False)
        out = write_output_folder(Path(args.out), self.name, {"ir_models.yaml": text,
                                                              "fit.json": json.dumps(report, indent=2)}, [path])
        print("\n".join(lines + [f"  outputs: {out}/ (ir_models.yaml, fit.json)"]))
        return 0


class FitMotion(Command):
    name = "epuck-fit-motion"
    summary = ("e-puck: velocity-model noise alpha1-4 from repeated straight runs, spins and turns (maximum "
               "likelihood, with sigmas and 95 % intervals)")

    def add_arguments(self, parser) -> None:
        parser.add_argument("trials", help="CSV: t, kind (0 straight, 1 spin, 2 turn), commanded (m or rad), "
                            "translation_error (m), rotation_error (rad); one row per trial")
        parser.add_argument("--out", required=True, help="output folder: velocity_noise.yaml, fit.json")

    def run(self, args) -> int:
        path = Path(args.trials)
        check_output_folder(Path(args.out), [path])
        columns = ("kind", "commanded", "translation_error", "rotation_error")
        data = read_csv_stream(path, "trials", columns)
        kind, commanded, et, er = (data.column(c) for c in columns)
        if not np.all(np.isin(kind, list(fitting().KINDS))) or np.any(commanded == 0):
            raise DataError(f"{path}: kind must be 0, 1 or 2 and commanded non-zero on every row")
        fits = fitting().fit_alphas(kind, commanded, et, er)
        missing = [a for a in ("alpha1", "alpha2", "alpha3", "alpha4") if a not in fits]
        if missing:
            raise DataError(f"{path}: {', '.join(missing)} need two or more trials of their kind (alpha1, alpha3: "
                            "straight; alpha2: spin; alpha4: turn)")
        alpha = [fits[f"alpha{i}"].value for i in range(1, 5)]
        report = {name: vars(f) for name, f in fits.items()}
        units = {"alpha1": "-", "alpha2": "m/rad", "alpha3": "rad/m", "alpha4": "-"}
        lines = [f"epuck-fit-motion: {path.name}: {len(kind)} trials"]
        for name, f in fits.items():
            lines.append(f"  {name} = {f.value:.4g} +- {f.sigma:.2g} {units[name]} (95 %: {f.interval[0]:.3g} .. "
                         f"{f.interval[1]:.3g}; {f.trials} trials; mean error per unit {f.mean_ratio:+.3g} +- "
                         f"{f.mean_ratio_sigma:.2g})")
        text = ("# velocity-model noise fitted by fusionkit epuck-fit-motion (SI units): merge into an epuck "
                "description\n") + yaml.safe_dump({"velocity_noise": {"alpha": [float(a) for a in alpha]}})
        out = write_output_folder(Path(args.out), self.name, {"velocity_noise.yaml": text,
                                                              "fit.json": json.dumps(report, indent=2)}, [path])
        print("\n".join(lines + [f"  outputs: {out}/ (velocity_noise.yaml, fit.json)"]))
        return 0


COMMANDS = [FitIr, FitMotion]
