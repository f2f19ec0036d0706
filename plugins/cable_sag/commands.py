"""`fusionkit cable-lengths`: the encoder readings a calibrated cable robot predicts at given poses
(docs/models/cable_sag.md#predicting-cable-lengths) -- what validating a calibration on another recording needs.

The robot description with a calibration file over it (`fusionkit run`'s calibration.yaml: pulleys, offsets and,
when estimated, the weight per length), and end-effector poses (a TUM file: t x y z qx qy qz qw). Straight cables
(`--rigid`, or a description whose cables weigh nothing) over the description's swivelling pulleys
(cables.pulley_radius), as cable.length models them; else the catenary at each pose as cable.catenary models it,
with each cable's pull at its attachment."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusionkit.api import (Command, ConfigError, cable_robot, check_output_folder, load_robot_description,
                           pulley_cables, read_tum, write_output_folder)

from .measured_geometry import hanging


def _csv(header: list[str], columns: list[np.ndarray]) -> str:
    rows = np.column_stack(columns)
    return ",".join(header) + "\n" + "\n".join(",".join(f"{x:.9g}" for x in row) for row in rows) + "\n"


class CableLengths(Command):
    name = "cable-lengths"
    summary = ("cable robot: the encoder readings a calibration predicts at given end-effector poses (straight cables "
               "over swivelling pulleys, or catenaries with each cable's pull); writes lengths.csv (and tensions.csv)")

    def add_arguments(self, parser) -> None:
        parser.add_argument("description", help="the robot description: a shipped one by name or a YAML file")
        parser.add_argument("--poses", required=True, help="TUM file of end-effector poses (t x y z qx qy qz qw)")
        parser.add_argument("--calibration", help="calibration file over the description (fusionkit run's "
                            "calibration.yaml)")
        parser.add_argument("--robot", help="the robot's name in the calibration file (when it has several)")
        parser.add_argument("--weight", metavar="PARAMETER", help="the calibration's weight-per-length parameter "
                            "(N/m; default: the description's cables.weight_per_length)")
        parser.add_argument("--rigid", action="store_true", help="straight cables (cable.length's model)")
        parser.add_argument("--out", required=True, help="output folder: lengths.csv (t, l0..), with catenaries "
                            "tensions.csv (t, H0.., V0.., N); replaced only when new, empty or an earlier output")

    def run(self, args) -> int:
        poses = Path(args.poses)
        inputs = [poses] + ([Path(args.calibration)] if args.calibration else [])
        check_output_folder(Path(args.out), inputs)
        desc = load_robot_description(args.description, calibration=args.calibration, robot=args.robot)
        robot = cable_robot(desc)
        pulleys = np.array([np.asarray(v, float) for v in desc.parameters["pulley"].values])
        offsets = np.array([float(v) for v in desc.parameters["offset"].values])
        w = 0.0 if args.rigid else self._weight(desc, robot, args.weight)
        from scipy.spatial.transform import Rotation  # here, not when fusionkit loads its plugins
        measured = read_tum(poses, "poses")  # one located error for a malformed file
        t, xyzq = measured.t, measured.pose_array()
        R, p = Rotation.from_quat(xyzq[:, 3:]).as_matrix(), xyzq[:, :3]
        columns = [f"l{i}" for i in range(robot.n)]
        files = {}
        if w == 0.0:
            attached = np.einsum("kij,nj->kni", R, robot.attachments) + p[:, None, :]
            lengths = np.column_stack([pulley_cables(attached[:, i], np.broadcast_to(pulleys[i], attached[:, i].shape),
                                                     robot.pulley_radius, robot.swivel_axis)[0]
                                       for i in range(robot.n)])
            what = "straight cables" + (f" over {robot.pulley_radius:g} m pulleys" if robot.pulley_radius else "")
        else:
            if robot.pulley_radius > 0:
                raise ConfigError(f"{desc.name}: cables.pulley_radius {robot.pulley_radius:g} m: the catenary starts at "
                                  "a fixed exit point; predict with --rigid, or remove the radius")
            if robot.mass is None:
                raise ConfigError(f"{desc.name}: no end_effector.mass: the catenaries' forces come from it")
            hung = hanging(R, p, np.broadcast_to(pulleys, (len(t),) + pulleys.shape), robot.attachments, robot.com,
                           robot.gravity * float(robot.mass), w)
            lengths = hung.lengths
            files["tensions.csv"] = _csv(["t"] + [f"H{i}" for i in range(robot.n)] + [f"V{i}" for i in range(robot.n)],
                                         [t, hung.horizontal, hung.vertical])
            what = f"catenaries of {w:g} N/m"
        files["lengths.csv"] = _csv(["t"] + columns, [t, lengths + offsets])
        write_output_folder(Path(args.out), self.name, files)
        print(f"cable-lengths: {len(t)} poses, {robot.n} cables, {what}: {', '.join(sorted(files))} in {args.out}")
        return 0

    @staticmethod
    def _weight(desc, robot, parameter: str | None) -> float:
        if parameter is None:
            return float(robot.weight_per_length or 0.0)
        if parameter not in desc.parameters:
            raise ConfigError(f"--weight {parameter}: the description has no such parameter; it has "
                              f"{', '.join(sorted(desc.parameters))}")
        return float(desc.parameters[parameter].values[0])


COMMANDS = [CableLengths]
