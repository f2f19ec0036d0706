"""The plugin's own tests: what every fusionkit plugin author should run.

    pip install -e examples/fusionkit-altimeter      # or your package
    pytest examples/fusionkit-altimeter/tests
"""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest

import fusionkit
from fusionkit.testing import ContractFailure, FactorExample, check_factor_contract, check_factor_example
from fusionkit_altimeter.factors import AltimeterHeight, altimeter_factor
from fusionkit_altimeter.residuals import height_residual

DEMO = Path(__file__).resolve().parents[1] / "configs" / "demo.yaml"


def test_contract():
    """Zero residual at the example, right shapes, analytic = numerical Jacobians (also away
    from the example's values)."""
    check_factor_contract(AltimeterHeight)


def test_residual_value():
    pose = gtsam.Pose3(gtsam.Rot3.Rz(0.3), np.array([1.0, 2.0, 3.0]))
    assert height_residual(pose, 0.5, 3.2)[0] == pytest.approx(0.3)


def test_wrong_jacobian_is_caught():
    """The contract would catch the classic mistake: the world z axis instead of R's third row."""
    def wrong(measured, this, values, H):
        e = height_residual(values.atPose3(this.keys()[0]), values.atDouble(this.keys()[1]), measured, H)
        if H is not None:
            H[0] = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
        return e

    example = AltimeterHeight.example(np.random.default_rng(0))
    measured = float(example.values.atPose3(0).translation()[2] + example.values.atDouble(1))
    factor = gtsam.CustomFactor(example.factor.noiseModel(), example.factor.keys(),
                                lambda this, v, H: wrong(measured, this, v, H))
    with pytest.raises(ContractFailure, match="Jacobian block 0"):
        check_factor_example(FactorExample(factor, example.values), "wrong")
    assert altimeter_factor(0, 1, measured, example.factor.noiseModel()).dim() == 1


def test_installed():
    """The entry point works: the registry lists what the plugin provides."""
    from fusionkit.plugins import registry
    reg = registry()
    assert reg.provider[("factor_types", "altimeter.height")] == "altimeter"
    assert reg.provider[("simulators", "altimeter.demo")] == "altimeter"


def test_demo_estimates_bias():
    result = fusionkit.run(DEMO)
    est = result.parameters["drone"]["baro_bias"]
    value, sigma = est.values[0], est.sigma[0][0]
    assert abs(value - 1.7) < 3 * sigma and sigma < 0.03
    assert result.evaluation["trajectories"]["drone"]["ate_rmse_m"] < 0.15
