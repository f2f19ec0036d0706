"""`fusionkit select-poses`: D-optimal configurations for a serial arm's calibration, chosen before any
data are taken, with the parameter sigmas they predict (selection.py;
docs/models/serial_arm.md#pose-selection)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fusionkit.api import (Command, ConfigError, check_output_folder, compared_with_random, load_robot_description,
                           read_csv_stream, write_output_folder)

from .selection import KINDS, design_of, select
from .simulators import random_configurations
from .urdf import urdf_path

DEFAULT_CANDIDATES = 1000  # random candidates when no file is given
DRAWS = 20                 # random picks the selection is compared with, per count
SHOWN = 10                 # parameters printed, worst first


def _positive(value, option: str) -> None:
    if value is not None and value <= 0:
        raise ConfigError(f"{option} {value}: expected a positive number")


class SelectPoses(Command):
    name = "select-poses"
    summary = ("serial arm: choose N calibration configurations (D-optimal, from candidates) and predict the "
               "parameter sigmas before any data are taken")

    def add_arguments(self, parser) -> None:
        parser.add_argument("description", help="a serial_arm robot description: a shipped name (ur10_tracker) "
                            "or a YAML file")
        parser.add_argument("--count", type=int, required=True, metavar="N", help="configurations to choose")
        source = parser.add_mutually_exclusive_group()
        source.add_argument("--candidates", metavar="FILE.csv", help="candidate configurations: a CSV with `t` "
                            "first and a column per joint of the description (other columns ignored)")
        source.add_argument("--random", type=int, metavar="M", help=f"M candidates drawn uniformly within the "
                            f"joint limits, at most +-pi, as arm.sim does (default {DEFAULT_CANDIDATES})")
        parser.add_argument("--seed", type=int, default=0, help="seed of the random candidates and comparisons")
        parser.add_argument("--measurement", choices=KINDS, default="pose",
                            help="6-D pose tracker or 3-D position (laser) tracker (default pose)")
        parser.add_argument("--sigma-rotation", type=float, default=1e-4, metavar="RAD",
                            help="tracker 1-sigma per rotation axis (pose; default 1e-4)")
        parser.add_argument("--sigma-translation", type=float, default=1e-4, metavar="M",
                            help="tracker 1-sigma per axis, m (default 1e-4)")
        parser.add_argument("--out", required=True, help="output folder: configurations.csv, selection.json; "
                            "replaced only when it is new, empty or an earlier fusionkit output")

    def run(self, args) -> int:
        for option in ("count", "random", "sigma_rotation", "sigma_translation"):
            _positive(getattr(args, option), "--" + option.replace("_", "-"))
        inputs = [Path(args.candidates)] if args.candidates else []
        desc = load_robot_description(args.description)
        if desc.model != "serial_arm":
            raise desc.error(("model",), f"a {desc.model!r} robot; select-poses needs a serial_arm description")
        inputs += [Path(desc.doc.file), urdf_path(str(desc.extra["urdf"]), Path(desc.doc.file).parent)]
        check_output_folder(Path(args.out), inputs)  # before any work
        design = design_of(desc)
        if not design.names:
            raise desc.error(("kinematics",), "no kinematic parameter to estimate (kinematics: base, tool, "
                             "joint_offsets, placements, not all fixed); nothing to choose configurations for")
        joints = design.chain.joint_names
        rng = np.random.default_rng(args.seed)
        if args.candidates:
            stream = read_csv_stream(Path(args.candidates), "candidates", tuple(joints))
            candidates = stream.values[:, [stream.columns.index(j) for j in joints]]
            origin = f"{len(candidates)} candidates from {args.candidates}"
        else:
            candidates = random_configurations(design.chain, args.random or DEFAULT_CANDIDATES, rng)
            origin = f"{len(candidates)} random candidates (seed {args.seed})"
        if args.count > len(candidates):
            raise ConfigError(f"--count {args.count}: more than the {len(candidates)} candidates; expected at most "
                              f"{len(candidates)}")
        pose = args.measurement == "pose"
        sigma = np.array([args.sigma_rotation] * 3 * pose + [args.sigma_translation] * 3)
        chosen = select(design, candidates, args.measurement, sigma, args.count)
        comparison = compared_with_random(chosen, (args.count, 3 * args.count), DRAWS, rng)
        document = self._document(args, design, chosen, comparison, origin)
        table = "t," + ",".join(joints) + "\n" + "".join(
            f"{i}," + ",".join(format(x, ".17g") for x in q) + "\n" for i, q in enumerate(candidates[chosen.indices]))
        out = write_output_folder(Path(args.out), "select-poses",
                                  {"configurations.csv": table, "selection.json": json.dumps(document, indent=2)},
                                  inputs)
        print("\n".join(self._summary(args, design, chosen, comparison, origin)))
        print(f"  outputs: {out}/ (configurations.csv, selection.json)")
        return 0

    @staticmethod
    def _document(args, design, chosen, comparison: dict, origin: str) -> dict:
        names = [design.names[j] for j in chosen.kept]
        return {
            "description": args.description, "measurement": args.measurement,
            "tracker_sigma": {"rotation": args.sigma_rotation, "translation": args.sigma_translation}
            if args.measurement == "pose" else {"translation": args.sigma_translation},
            "candidates": origin, "count": args.count, "candidate_rows": chosen.indices.tolist(),
            "log_det": chosen.log_det, "exchange_swaps": chosen.swaps,
            "log_det_of": "the information matrix of the kept parameters, each scaled by its prior sigma (1 SI unit "
                          "without one), priors included",
            "parameters": {name: {"sigma": float(s), "unit": design.units[j],
                                  "prior_sigma": float(design.prior[j]) if np.isfinite(design.prior[j]) else None}
                           for name, s, j in zip(names, chosen.sigma, chosen.kept)},
            "held": [design.names[j] for j in chosen.held],
            "compared_with_random": {str(n): c for n, c in comparison.items()},
        }

    @staticmethod
    def _summary(args, design, chosen, comparison: dict, origin: str) -> list[str]:
        kept = len(chosen.kept)
        lines = [f"select-poses: {args.description}: {args.count} of {origin}, {args.measurement} tracker; "
                 f"{kept} of {kept + len(chosen.held)} kinematic parameters kept, {len(chosen.held)} held (no "
                 f"candidate identifies them); log det {chosen.log_det:.2f}, {chosen.swaps} exchange swap(s)"]
        if comparison:
            lines.append("  predicted sigmas / those of random picks of the same candidates (median of "
                         f"{DRAWS}): " + "; ".join(f"{n} random: x{c['geometric_mean']:.2f} geometric mean, "
                                                   f"x{c['worst']:.2f} worst" for n, c in comparison.items()))
        lines.append("  predicted 1-sigma, worst first (relative to the prior):")
        order = np.argsort(-chosen.sigma / chosen.scale)
        for i in order[:SHOWN]:
            j = chosen.kept[i]
            prior = f" (prior {design.prior[j]:.2g})" if np.isfinite(design.prior[j]) else " (no prior)"
            lines.append(f"    {design.names[j]:<40} {chosen.sigma[i]:.2g} {design.units[j]}{prior}")
        if kept > SHOWN:
            lines.append(f"    ... {kept - SHOWN} more in selection.json")
        return lines


COMMANDS = [SelectPoses]
