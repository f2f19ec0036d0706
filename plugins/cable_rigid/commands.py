"""`fusionkit select-cable-poses`: D-optimal static poses for a cable robot's pulley and offset calibration, chosen
before any data are taken, with the sigmas they predict (design.py; docs/models/cable_rigid.md#pose-selection)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fusionkit.api import (Command, ConfigError, check_output_folder, compared_with_random, load_robot_description,
                           read_csv_stream, write_output_folder)

from .design import design_of, random_candidates, select

DEFAULT_CANDIDATES = 500
DRAWS = 20  # random picks the choice is compared with, per count


class SelectCablePoses(Command):
    name = "select-cable-poses"
    summary = ("cable robot: choose N static poses (D-optimal, from candidates in the workspace with every cable "
               "taut) for the pulley and offset calibration, and predict their sigmas before any data are taken")

    def add_arguments(self, parser) -> None:
        parser.add_argument("description", help="a cdpr robot description: a shipped name (arascam) or a YAML file")
        parser.add_argument("--count", type=int, required=True, metavar="N", help="poses to choose")
        source = parser.add_mutually_exclusive_group()
        source.add_argument("--candidates", metavar="FILE.csv", help="candidate positions of the level "
                            "end-effector: a CSV with `t` first and columns x, y, z (m, base frame)")
        source.add_argument("--random", type=int, metavar="M", help=f"M taut candidates drawn in the workspace "
                            f"(default {DEFAULT_CANDIDATES})")
        parser.add_argument("--seed", type=int, default=0, help="seed of the random candidates and comparisons")
        parser.add_argument("--encoder-sigma", type=float, default=1e-3, metavar="M",
                            help="cable-length encoder 1-sigma (default 0.001)")
        parser.add_argument("--pose-sigma-rotation", type=float, default=2e-3, metavar="RAD",
                            help="motion capture 1-sigma per rotation axis (default 0.002)")
        parser.add_argument("--pose-sigma-translation", type=float, default=1e-3, metavar="M",
                            help="motion capture 1-sigma per axis (default 0.001)")
        parser.add_argument("--out", required=True, help="output folder: poses.tum, selection.json; replaced only "
                            "when it is new, empty or an earlier fusionkit output")

    def run(self, args) -> int:
        for option in ("count", "random", "encoder_sigma", "pose_sigma_rotation", "pose_sigma_translation"):
            value = getattr(args, option)
            if value is not None and value <= 0:
                raise ConfigError(f"--{option.replace('_', '-')} {value}: expected a positive number")
        desc = load_robot_description(args.description)
        if desc.model != "cdpr":
            raise desc.error(("model",), f"a {desc.model!r} robot; select-cable-poses needs a cdpr description")
        inputs = [Path(desc.doc.file)] + ([Path(args.candidates)] if args.candidates else [])
        check_output_folder(Path(args.out), inputs)  # before any work
        data = desc.doc.data
        design = design_of(data)
        rng = np.random.default_rng(args.seed)
        if args.candidates:
            stream = read_csv_stream(Path(args.candidates), "candidates", ("x", "y", "z"))
            candidates = np.column_stack([stream.column(c) for c in "xyz"])
            origin = f"{len(candidates)} candidates from {args.candidates}"
        else:
            candidates = random_candidates(data, design, args.random or DEFAULT_CANDIDATES, rng)
            origin = f"{len(candidates)} random taut candidates (seed {args.seed})"
        if args.count > len(candidates):
            raise ConfigError(f"--count {args.count}: more than the {len(candidates)} candidates; expected at most "
                              f"{len(candidates)}")
        mocap = {"rotation": args.pose_sigma_rotation, "translation": args.pose_sigma_translation}
        choice = select(design, candidates, args.count, args.encoder_sigma, mocap)
        comparison = compared_with_random(choice, (args.count, 2 * args.count, 3 * args.count), DRAWS, rng)
        chosen = candidates[choice.indices]
        poses = "".join(f"{i} {x:.9g} {y:.9g} {z:.9g} 0 0 0 1\n" for i, (x, y, z) in enumerate(chosen))
        document = {"description": args.description, "count": args.count, "candidates": origin,
                    "candidate_rows": choice.indices.tolist(), "encoder_sigma": args.encoder_sigma,
                    "pose_sigma": mocap, "log_det": choice.log_det, "exchange_swaps": choice.swaps,
                    "parameters": {name: {"sigma": float(s), "unit": unit,
                                          "prior_sigma": float(p) if np.isfinite(p) else None}
                                   for name, s, unit, p in zip(design.names, choice.sigma, design.units,
                                                               design.prior)},
                    "compared_with_random": {str(n): c for n, c in comparison.items()}}
        out = write_output_folder(Path(args.out), "select-cable-poses",
                                  {"poses.tum": poses, "selection.json": json.dumps(document, indent=2)}, inputs)
        pulley = choice.sigma[:3 * design.geometry.n]
        offset = choice.sigma[3 * design.geometry.n:]
        print(f"select-cable-poses: {args.description}: {args.count} of {origin}; log det {choice.log_det:.2f}, "
              f"{choice.swaps} exchange swap(s)")
        print(f"  predicted 1-sigma: pulleys {1e3 * pulley.min():.2g} .. {1e3 * pulley.max():.2g} mm per axis (rms "
              f"{1e3 * np.sqrt(np.mean(pulley ** 2)):.2g} mm), offsets {1e3 * offset.min():.2g} .. "
              f"{1e3 * offset.max():.2g} mm")
        print("  predicted sigmas / those of random picks of the candidates (median of "
              f"{DRAWS}): " + "; ".join(f"{n} random: x{c['geometric_mean']:.2f} geometric mean, x{c['worst']:.2f} "
                                        "worst" for n, c in comparison.items()))
        print(f"  outputs: {out}/ (poses.tum, selection.json)")
        return 0


COMMANDS = [SelectCablePoses]
