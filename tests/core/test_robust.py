"""A robust kernel chosen per factor holds the estimate when 10% of absolute poses are outliers."""

from __future__ import annotations

import numpy as np

import fusionkit
from fusionkit.simulate import write_dataset


def _corrupt_mocap(folder, share=0.1, jump=0.8, seed=1):
    path = folder / "data" / "mocap.tum"
    header, *rows = path.read_text().splitlines()
    data = np.array([[float(x) for x in r.split()] for r in rows])
    rng = np.random.default_rng(seed)
    bad = rng.choice(len(data), size=int(share * len(data)), replace=False)
    data[bad, 1:4] += rng.choice([-1, 1], size=(len(bad), 3)) * jump
    np.savetxt(path, data, fmt="%.9f", header=header.lstrip("# "))
    return len(bad)


def test_huber_keeps_the_ate_within_1_3x_clean_under_outliers_that_triple_least_squares(tmp_path):
    folder = tmp_path / "sim"
    write_dataset("pose.scaled_vo", folder, ["duration=15", "mocap_every=10"], seed=4)
    config = folder / "config.yaml"
    clean = fusionkit.run(config).evaluation["trajectories"]["cam"]["ate_rmse_m"]
    assert _corrupt_mocap(folder) >= 4
    plain = fusionkit.run(config, ["solver.max_cost_ratio=1e6"])
    robust = fusionkit.run(config, ["factors.1.robust={kernel: huber, k: 1.345}"])
    ate_plain = plain.evaluation["trajectories"]["cam"]["ate_rmse_m"]
    ate_robust = robust.evaluation["trajectories"]["cam"]["ate_rmse_m"]
    truth_scale = 2.5
    assert ate_plain > 3 * clean        # the outliers drag the plain least-squares solution
    assert ate_robust < 1.3 * clean     # the kernel holds the error near the outlier-free level
    scale = robust.parameters["cam"]["vo_scale"]
    assert abs(scale.values[0] - truth_scale) < 0.05
