"""report.json evaluation.baselines: what each sensor alone gives (FactorType.baseline), against the truth beside
the fused estimate: the VO dead-reckoned at the estimated scale, the cable robot's forward kinematics."""

from __future__ import annotations

from pathlib import Path

from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config

REPO = Path(__file__).resolve().parents[2]


def _vo_baseline(vo_sigma: dict) -> dict:
    with simulated_config("pose.scaled_vo", {"duration": 10.0, "vo_sigma": vo_sigma}, seed=2) as config:
        return estimate(config).evaluation["baselines"]["cam"]["visual_odometry"]


def test_noiseless_vo_dead_reckoned_at_the_estimated_scale_follows_the_truth_and_noisy_vo_drifts():
    exact = _vo_baseline({"rotation": 0.0, "translation": 0.0})
    drifting = _vo_baseline({"rotation": 0.004, "translation": 0.004})
    assert exact["matched"] == 300
    # measured 0.015 m, the fused estimate's own error (0.014): the start pose and the scale are estimates
    assert exact["position_rmse_m"] < 1.2 * exact["fused_position_rmse_m"] + 1e-3
    assert drifting["position_rmse_m"] > 5 * exact["position_rmse_m"]   # measured 0.21 m
    assert drifting["fused_position_rmse_m"] < drifting["position_rmse_m"]


def test_the_cable_robot_reports_forward_kinematics_alone_and_fusion_beats_it():
    config = load_config(REPO / "configs" / "quickstart.yaml", ["sources.0.params.duration=10", "output.plots=false"])
    b = estimate(config).evaluation["baselines"]["cdpr"]
    fk, vo = b["forward_kinematics"], b["visual_odometry"]
    assert fk["matched"] == vo["matched"] == 300
    assert fk["fused_position_rmse_m"] < fk["position_rmse_m"] < 0.05
    assert vo["fused_position_rmse_m"] == fk["fused_position_rmse_m"]  # the same states, the same estimate
