"""The wrenches of a cable robot's end-effector statics, shared by the cable families (public in fusionkit.api): what
cables pulling at their attachments exert, and what the end-effector's weight does, both about the end-effector's
origin in the base frame (force N; moment N m)."""

from __future__ import annotations

import numpy as np


def cable_pull_wrenches(arms: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """W (N, n, 6): row i the wrench [d_i; r_i x d_i] of a unit pull along `directions` d_i (N, n, 3) at the
    attachment r_i = R b_i (`arms`, N, n, 3); W^T tau is the cables' wrench for tensions tau (N, n)."""
    return np.concatenate([directions, np.cross(arms, directions)], axis=2)


def weight_wrench(R: np.ndarray, com: np.ndarray, weight) -> np.ndarray:
    """(N, 6): the weight (N; a number or (N,)) pulling down (-z) at the centre of mass com ((3,) or (N, 3), body
    frame) of end-effectors at orientations R (N, 3, 3)."""
    gravity = np.zeros((len(R), 3))
    gravity[:, 2] = -np.asarray(weight, float)
    lever = np.matmul(R, np.asarray(com, float)[..., None])[..., 0]
    return np.concatenate([gravity, np.cross(lever, gravity)], axis=1)
