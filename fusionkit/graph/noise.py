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
