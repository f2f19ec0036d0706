"""FIGAROH's UR10 calibration recording (`../shared/data/arm_ur10_figaroh`, see its README) in
fusionkit's stream formats, and the config that calibrates the arm from it.

The recording is 23 static samples of one CSV: the marker position (x1, y1, z1, m) and orientation as
Pinocchio roll-pitch-yaw (phix1, phiy1, phiz1, rad: R = Rz(phiz) Ry(phiy) Rx(phix)) in the measurement
frame, and the six joint readings (rad) under their URDF names. `convert` writes them as two stream
CSVs with the sample index as time: `joints.csv` (t + joint names) and `tracker.csv` (t x y z qx qy qz qw).

    python research/ur10_figaroh.py OUT      # writes OUT/joints.csv, OUT/tracker.csv
    fusionkit run configs/arm_ur10_real.yaml --set sources.0.path=OUT/joints.csv \\
        --set sources.1.path=OUT/tracker.csv [--set robots.arm.description.urdf=<dataset>/ur10.urdf]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

if __package__ in (None, ""):  # run as a script: the repository root on the path for `research.`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from research.external_data import external_data  # noqa: E402

DATASET = "arm_ur10_figaroh"
CONFIG = Path(__file__).resolve().parents[1] / "configs" / "arm_ur10_real.yaml"
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")
# README of the dataset: FIGAROH 1.0.2 and a scipy least-squares fit on the same file (mm, deg, s)
PUBLISHED = {
    "nominal": {"in_sample": (134.5, 29.5)},
    "base_marker": {"in_sample": (3.64, 0.524), "loo": (4.12, 0.571), "loo_s": {"FIGAROH": 19.8, "scipy": 1.7}},
    "offsets": {"in_sample": (3.45, 0.517), "loo": (4.03, 0.583), "loo_s": {"FIGAROH": 9.6}},
    "full": {"in_sample": (2.98, 0.338), "loo": (3.97, 0.419), "loo_s": {"FIGAROH": 31.7, "scipy": 5.8}},
}

def folder() -> Path:
    return external_data(DATASET)


def read_recording(path: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(joint readings (N, 6) rad, measured marker poses (N, 4, 4)) of `ur10_calibration.csv`."""
    data = np.genfromtxt(path or folder() / "ur10_calibration.csv", delimiter=",", names=True)
    q = np.column_stack([data[j] for j in JOINTS])
    T = np.tile(np.eye(4), (len(data), 1, 1))
    T[:, :3, :3] = Rotation.from_euler("xyz", np.column_stack([data[f"phi{a}1"] for a in "xyz"])).as_matrix()
    T[:, :3, 3] = np.column_stack([data[f"{a}1"] for a in "xyz"])
    return q, T


def write_streams(out: Path, rows: np.ndarray | None = None) -> tuple[Path, Path]:
    """joints.csv and tracker.csv of the recording's `rows` (all by default) in folder `out`; t is the sample index."""
    q, T = read_recording()
    rows = np.arange(len(q)) if rows is None else np.asarray(rows)
    t = rows.astype(float)[:, None]
    quat = Rotation.from_matrix(T[rows, :3, :3]).as_quat()  # x y z w
    out.mkdir(parents=True, exist_ok=True)
    joints, tracker = out / "joints.csv", out / "tracker.csv"
    np.savetxt(joints, np.hstack([t, q[rows]]), delimiter=",", header="t," + ",".join(JOINTS), comments="", fmt="%.17g")
    np.savetxt(tracker, np.hstack([t, T[rows, :3, 3], quat]), delimiter=",", header="t,x,y,z,qx,qy,qz,qw",
               comments="", fmt="%.17g")
    return joints, tracker


def overrides(joints: Path, tracker: Path) -> list[str]:
    """The `--set` assignments pointing configs/arm_ur10_real.yaml at converted streams and the dataset's URDF."""
    return [f"sources.0.path={joints}", f"sources.1.path={tracker}",
            f"robots.arm.description.urdf={folder() / 'ur10.urdf'}"]


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    for file in write_streams(Path(sys.argv[1])):
        print(file)
