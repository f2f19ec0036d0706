"""Do the reported position sigmas fit the errors against truth? A verdict per axis.

Errors of consecutive states of a smoothed trajectory are strongly correlated (a shared offset moves
many states together), so n states hold far fewer independent checks than n. The rules are chosen to
stay quiet in that case when the sigmas are right:

- overconfident: fewer than 90 % of the errors inside 3 sigma (ideal 99.7 %). With independent
  errors this flags sigmas about 1.8 times too small or worse; a correct sigma puts an error outside
  3 sigma with probability 0.3 %, however correlated the errors are.
- underconfident: more than 95 % inside 1 sigma (ideal 68.3 %), flagging sigmas about 2 times too
  large, judged only with at least 20 effective samples: a single shared error sits inside 1 sigma
  with probability 68 %, so few effective samples cannot tell.
"""

from __future__ import annotations

import numpy as np

OVERCONFIDENT_BELOW_3SIGMA = 90.0  # % inside 3 sigma
UNDERCONFIDENT_ABOVE_1SIGMA = 95.0  # % inside 1 sigma
MIN_EFFECTIVE_SAMPLES = 20


def effective_samples(z: np.ndarray) -> float:
    """n (1 - rho) / (1 + rho), the independent samples in a series of n whose lag-1 autocorrelation
    (about zero, so that a shared offset counts as correlation) is rho, as for a first-order
    autoregressive series; between 1 and n."""
    n = len(z)
    if n < 2 or not np.any(z):
        return float(n)
    rho = float(np.clip(np.sum(z[1:] * z[:-1]) / np.sum(z * z), 0.0, 1.0))
    return float(np.clip(n * (1.0 - rho) / (1.0 + rho), 1.0, n))


def sigma_check(z: np.ndarray, percent: dict[str, dict[str, float]]) -> dict:
    """Verdicts for errors normalized by their sigmas, z (n, d), and their shares inside 1/2/3 sigma
    (`position_consistency`): {effective_samples: {axis: ..}, overconfident: [axes], underconfident: [axes]}."""
    axes = list(percent)
    n_eff = {axis: effective_samples(z[:, i]) for i, axis in enumerate(axes)}
    over = [a for a in axes if percent[a]["3sigma"] < OVERCONFIDENT_BELOW_3SIGMA]
    under = [a for a in axes if percent[a]["1sigma"] > UNDERCONFIDENT_ABOVE_1SIGMA
             and n_eff[a] >= MIN_EFFECTIVE_SAMPLES]
    return {"effective_samples": n_eff, "overconfident": over, "underconfident": under}
