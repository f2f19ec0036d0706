"""covariances/<robot>.csv: the marginal covariance of every state's pose (`output: {state_covariances: true}`).

One row per state: `t` (s); `sx, sy, sz` the 1-sigma of the position along the world axes (m; planar
robots: `sx, sy`); then the upper triangle, row by row, of the covariance in GTSAM's tangent space of
the pose, `cov_<a>_<b>` with a, b in rx ry rz tx ty tz (pose3: rad about and m along the body axes, so
entries in rad^2, rad*m, m^2) or tx ty rz (pose2).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..pipeline import RunResult


def covariance_table(result: RunResult, robot: str) -> tuple[list[str], np.ndarray] | None:
    """(column names, rows) of one robot's file; None unless every estimated state has a covariance."""
    states = result.problem.states[robot]
    values, cov = result.solution.values, result.solution.covariances
    keys = [states.key(k) for k in range(len(states)) if values.exists(states.key(k))]
    sigma = result.position_sigma.get(robot)
    if not keys or sigma is None or not all(k in cov for k in keys):
        return None
    names = states.family.vartype.names()[1]
    upper = np.triu_indices(len(names))
    columns = ["t", *("sx", "sy", "sz")[: sigma.shape[1]], *(f"cov_{names[i]}_{names[j]}" for i, j in zip(*upper))]
    rows = np.column_stack([result.trajectories[robot].t, sigma, np.array([cov[k][upper] for k in keys])])
    return columns, rows


def write_state_covariances(result: RunResult, folder: Path) -> None:
    """covariances/<robot>.csv for each robot whose states have covariances (`folder` is created if any)."""
    tables = {robot: covariance_table(result, robot) for robot in result.problem.states}
    for robot, table in tables.items():
        if table is not None:
            folder.mkdir(exist_ok=True)
            columns, rows = table
            np.savetxt(folder / f"{robot}.csv", rows, delimiter=",", header=",".join(columns), comments="",
                       fmt=["%.9f"] + ["%.9g"] * (rows.shape[1] - 1))
