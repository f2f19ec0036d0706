"""The frame-level fit behind the identifiability diagnostic (docs/models/serial_arm.md#identifiability): the base
and tool moved to where one entry's measurements put them, every other kinematic parameter at its nominal value.

The regressor of a marker entry depends on where it is taken: a marker at the URDF's tool origin (a point3 tool
starting at zero) sits on the last wrist axis, whose offset then moves nothing -- held as unidentifiable though the
real marker, a few centimetres off the axis, determines it. Gauss-Newton on the entry's own residuals (the tracker
position e = t(B F(q) M) - z, or the pose e = Log(z^-1 B F(q) M)) over the base B and tool M only, from the nominal
values, gives the data-informed point (on at most 200 samples spread over the entry); a step that does not lower the
cost ends it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fusionkit.api import lie

from .vectorized_kinematics import marker_poses, pose_residuals, position_residuals
from .kinematics import Layout, Parameters

ROUNDS = 20
SAMPLES = 200  # at most this many samples, evenly spread, place the frames: a linearization point, not an estimate


def _residuals(chain, layout: Layout, p: Parameters, q: np.ndarray, measured: np.ndarray, kind: str,
               jacobians: bool):
    poses = marker_poses(chain, layout, q, p, jacobians)
    e, blocks = (position_residuals if kind == "position" else pose_residuals)(poses, measured)
    return e, blocks


def _moved(layout: Layout, p: Parameters, step: np.ndarray) -> Parameters:
    """p with the base and tool moved by a step in their tangents (right perturbations, as the graph's Pose3)."""
    base, tool, i = p.base, p.tool, 0
    if layout.base:
        base, i = np.asarray(p.base, float) @ lie.exp(step[:6]), 6
    if layout.tool == "pose3":
        tool = np.asarray(p.tool, float) @ lie.exp(step[i:i + 6])
    elif layout.tool:
        tool = np.asarray(p.tool, float).copy()
        tool[:3, 3] += step[i:i + 3]
    return replace(p, base=base, tool=tool)


def frame_fit(chain, layout: Layout, p: Parameters, q: np.ndarray, measured: np.ndarray, kind: str) -> Parameters:
    """`p` with its base and tool fitted to one entry's samples (joint values q (N, n), `measured` as the entry's
    the marker residual takes it); `p` itself when the entry has neither, is relative, or no step lowers the cost."""
    width = (6 if layout.base else 0) + ({"pose3": 6, "point3": 3}.get(layout.tool, 0))
    if kind not in ("position", "pose") or not width:
        return p
    every = max(1, len(q) // SAMPLES)
    q, measured = q[::every], measured[::every]
    e, blocks = _residuals(chain, layout, p, q, measured, kind, True)
    cost = float(np.sum(e * e))
    for _ in range(ROUNDS):
        frames = blocks[1:1 + bool(layout.base) + bool(layout.tool)]  # after the joint vector's block
        J = np.concatenate([np.asarray(b) for b in frames], axis=2).reshape(-1, width)
        step = np.linalg.lstsq(J, -e.ravel(), rcond=None)[0]
        trial = _moved(layout, p, step)
        e_new, blocks_new = _residuals(chain, layout, trial, q, measured, kind, True)
        new_cost = float(np.sum(e_new * e_new))
        if not new_cost < cost:
            break
        p, e, blocks, cost = trial, e_new, blocks_new, new_cost
        if np.linalg.norm(step) < 1e-12:
            break
    return p
