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
        parser.add_argument("--held-out", metavar="CSV", help="readings of another run (same columns): print the share "
                            "of them inside 1/2/3 sigma of each fitted model (68/95/99.7 %% if it holds)")

    def run(self, args) -> int:
        if args.unit <= 0:
            raise ConfigError(f"--unit {args.unit}: expected a positive length in m")
        path = Path(args.readings)
        inputs = [path] + ([Path(args.held_out)] if args.held_out else [])
        check_output_folder(Path(args.out), inputs)
        distance, sensor, reading = _readings(path)
        held_out = _readings(Path(args.held_out)) if args.held_out else None
        fits, report = {}, {"unit_m": args.unit, "sensors": {}}
        lines = [f"epuck-fit-ir: {path.name}: {len(reading)} readings at {distance.min():g} .. {distance.max():g} m, "
                 f"x unit {args.unit:g} m"]
        for s in np.unique(sensor).astype(int):
            rows = sensor == s
            try:
                fits[args.names.format(i=s)] = (s, fitting().fit_sensor(distance[rows], reading[rows], args.unit,
                                                                       args.max_terms))
            except ValueError as exc:
                raise DataError(f"{path}: sensor {s}: {exc}") from None
        # the models hold where every sensor's were fitted: outside, readings are censored
        fitted = [max(float(f.x[0]) for _, f in fits.values()) * args.unit,
                  min(float(f.x[-1]) for _, f in fits.values()) * args.unit]
        if fitted[0] >= fitted[1]:
            raise DataError(f"{path}: the sensors' fitted distances do not overlap (" + ", ".join(
                f"{n}: {f.x[0] * args.unit:g} .. {f.x[-1] * args.unit:g} m" for n, (_, f) in fits.items()) + ")")
        lines.append(f"  ir_range {fitted[0]:g} .. {fitted[1]:g} m: the distances every sensor's models were fitted on")
        models = {}
        for name, (s, fit) in fits.items():
            models[name] = {"mean": fit.mean_fit.terms, "variance": fit.var_fit.terms,
                            **({"dropout": round(fit.dropout, 6)} if fit.dropped else {}),
                            **({"saturation": fit.saturation} if fit.saturation is not None else {})}
            bank = fitting().sensor_bank(models[name], args.unit, fitted)
            entry = {"dropouts": fit.dropped, "dropout": fit.dropout, "saturation": fit.saturation,
                     "saturated_distances": fit.saturated, "weak_distances": fit.clipped,
                     "mean_rise_flattened": float(bank.sum_rise[0]), "x": fit.x.tolist(), "count": fit.count.tolist(),
                     "mean": fit.mean.tolist(), "variance": fit.var.tolist(), "mean_fit": _curve_report(fit.mean_fit),
                     "variance_fit": _curve_report(fit.var_fit)}
            inside = fitting().coverage(bank, distance[sensor == s], reading[sensor == s])
            entry["coverage_in_sample"] = inside.tolist()
            text = [f"  {name}: {len(fit.x)} distances fitted"
                    + (f", {fit.saturated} saturated at {fit.saturation:g}" if fit.saturated else "")
                    + (f", {fit.clipped} weak (readings clipped at 0) left out" if fit.clipped else "")
                    + (f"; {fit.dropped} drop-out(s) to 0, probability {fit.dropout:.3f}" if fit.dropped else "")
                    + f"; mean {len(fit.mean_fit.terms)} term(s), chi2/dof {fit.mean_fit.chi2_per_dof:.2f}"
                    + (f" (held flat where the sum rises, by up to {bank.sum_rise[0]:.1f})" if bank.sum_rise[0] > 0.05
                       else "")
                    + f"; variance {len(fit.var_fit.terms)} term(s), chi2/dof {fit.var_fit.chi2_per_dof:.2f}",
                    f"    inside 1/2/3 sigma: {_percent(inside)} of these readings"]
            if held_out is not None:
                rows = held_out[1] == s
                if rows.any():
                    outside = fitting().coverage(bank, held_out[0][rows], held_out[2][rows])
                    entry["coverage_held_out"] = outside.tolist()
                    text.append(f"    inside 1/2/3 sigma: {_percent(outside)} of {rows.sum()} held-out readings "
                                "(68/95/99.7 % if the model holds)")
            report["sensors"][name] = entry
            lines += text
        report["ir_range"] = fitted
        text = ("# IR sensor models fitted by fusionkit epuck-fit-ir: merge into an epuck description -- the models "
                "into its `sensors:`, and ir_range, the distances (m) they were fitted on (outside them readings are "
                "censored)\n") + yaml.safe_dump({"ir_distance_unit": args.unit, "ir_range": fitted,
                                                  "sensors": models}, sort_keys=False)
        out = write_output_folder(Path(args.out), self.name, {"ir_models.yaml": text,
                                                              "fit.json": json.dumps(report, indent=2)}, inputs)
        print("\n".join(lines + [f"  outputs: {out}/ (ir_models.yaml, fit.json)"]))
        return 0


def _percent(values) -> str:
    return "/".join(f"{v:.0f}" for v in values) + " %"


def _readings(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(distance m, sensor index, reading counts) of an IR calibration CSV; a bad row: DataError."""
    data = read_csv_stream(path, "readings", ("distance", "sensor", "reading"), indexed=True)
    distance, sensor, reading = (data.column(c) for c in ("distance", "sensor", "reading"))
    if np.any(distance < 0) or np.any(sensor != np.round(sensor)) or np.any(sensor < 0):
        raise DataError(f"{path}: distance must be >= 0 (m) and sensor a non-negative integer on every row")
    return distance, sensor, reading


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
