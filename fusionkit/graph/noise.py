"""Noise models from sigmas, with the optional robust kernel of a factor entry."""

from __future__ import annotations

import gtsam
import numpy as np

KERNELS = {
    "huber": (gtsam.noiseModel.mEstimator.Huber, 1.345),
    "cauchy": (gtsam.noiseModel.mEstimator.Cauchy, 0.1),
    "tukey": (gtsam.noiseModel.mEstimator.Tukey, 4.6851),
    "geman_mcclure": (gtsam.noiseModel.mEstimator.GemanMcClure, 1.0),
    "dcs": (gtsam.noiseModel.mEstimator.DCS, 1.0),
    "welsch": (gtsam.noiseModel.mEstimator.Welsch, 2.9846),
    "fair": (gtsam.noiseModel.mEstimator.Fair, 1.3998),
}


def pose_sigma_schema(allow_zero: bool = False) -> dict:
    """The one schema of a pose's `sigma: {rotation: rad, translation: m}`: both keys required, each
    > 0 (a factor's noise); with `allow_zero`, >= 0 (a simulator's noise level: 0 = noiseless)."""
    number = {"type": "number", "minimum" if allow_zero else "exclusiveMinimum": 0}
    return {"type": "object", "properties": {"rotation": number, "translation": number},
            "required": ["rotation", "translation"], "additionalProperties": False}


POSE_SIGMA_SCHEMA = pose_sigma_schema()


def pose_sigmas(sigma: dict, planar: bool) -> np.ndarray:
    """Per tangent axis, in GTSAM's order, from `{rotation, translation}`: Pose3 [rot x3 (rad),
    trans x3 (m)]; Pose2 [x, y (m), theta (rad)]."""
    if planar:
        return np.array([sigma["translation"], sigma["translation"], sigma["rotation"]], dtype=float)
    return np.array([sigma["rotation"]] * 3 + [sigma["translation"]] * 3, dtype=float)


def gaussian(sigmas) -> gtsam.noiseModel.Base:
    """Diagonal (or isotropic, for one sigma) Gaussian noise model in the residual's units."""
    s = np.atleast_1d(np.asarray(sigmas, dtype=float))
    if s.size == 1:
        return gtsam.noiseModel.Isotropic.Sigma(1, float(s[0]))
    if np.all(s == s[0]):
        return gtsam.noiseModel.Isotropic.Sigma(s.size, float(s[0]))
    return gtsam.noiseModel.Diagonal.Sigmas(s)


def with_kernel(model: gtsam.noiseModel.Base, robust: dict | None) -> gtsam.noiseModel.Base:
    """Wrap `model` in the kernel named by a config `robust:` block ({kernel, k}); k is in sigmas."""
    if not robust:
        return model
    cls, default_k = KERNELS[robust["kernel"]]
    return gtsam.noiseModel.Robust.Create(cls.Create(float(robust.get("k", default_k))), model)


def noise_scale(spec) -> float:
    """The factor entry's `noise_scale:` as a number (absent: 1; `estimate` before its first estimate: 1)."""
    scale = spec.get("noise_scale", 1.0) if spec is not None else 1.0
    return 1.0 if scale == "estimate" else float(scale)
