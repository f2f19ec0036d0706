"""The factor contract holds for every installed factor type, and the checker catches violations:
a wrong Jacobian (at truth, or only away from it), a non-zero residual at the consistent values,
and a residual of the wrong size."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np
import pytest

from fusionkit.api import FactorType
from fusionkit.plugins import registry
from fusionkit.testing import (ContractFailure, FactorExample, check_factor_contract, check_factor_example,
                               numerical_jacobians)

FACTOR_TYPES = registry().names("factor_types")
BUILTIN = {"pose.absolute", "pose.origin", "pose.relative", "pose.scaled_relative", "pose.co_registration",
           "parameter.random_walk"}


def test_every_builtin_factor_type_is_registered():
    assert BUILTIN <= set(FACTOR_TYPES)


@pytest.mark.parametrize("name", FACTOR_TYPES)
def test_every_installed_factor_type_meets_the_contract(name):
    check_factor_contract(registry().get("factor_types", name))


# --- a scalar factor e = x^2 - z with a choice of Jacobian -----------------------------------------

def _square_error(z: float, jacobian, this: gtsam.CustomFactor, v: gtsam.Values, H) -> np.ndarray:
    x = v.atDouble(this.keys()[0])
    if H is not None:
        H[0] = np.array([[jacobian(x, z)]])
    return np.array([x * x - z])


def square_factor(z: float, jacobian) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, 0.1), [0], partial(_square_error, z, jacobian))


def _values(x: float) -> gtsam.Values:
    v = gtsam.Values()
    v.insert(0, x)
    return v


def right(x, z):
    return 2 * x


def wrong_everywhere(x, z):
    return 3 * x


def right_only_at_truth(x, z):
    return 2 * np.sqrt(z)  # linearized at the measurement, not at the current value


def test_numerical_jacobian_matches_hand_derivative():
    """d(whitened e)/dx = 2x / sigma for e = x^2 - z."""
    J = numerical_jacobians(square_factor(4.0, right), _values(1.5))
    assert J[0].shape == (1, 1)
    assert J[0][0, 0] == pytest.approx(2 * 1.5 / 0.1, rel=1e-8)


def test_a_correct_custom_factor_passes():
    check_factor_example(FactorExample(square_factor(4.0, right), _values(2.0)), "square")


def test_a_wrong_jacobian_is_caught():
    with pytest.raises(ContractFailure, match=r"square: Jacobian block 0 at truth differs .* by 20"):
        check_factor_example(FactorExample(square_factor(4.0, wrong_everywhere), _values(2.0)), "square")


def test_a_jacobian_right_only_at_truth_is_caught_away_from_it():
    with pytest.raises(ContractFailure, match="Jacobian block 0 away from truth"):
        check_factor_example(FactorExample(square_factor(4.0, right_only_at_truth), _values(2.0)), "square")


def test_a_nonzero_residual_at_truth_is_caught():
    with pytest.raises(ContractFailure, match=r"residual at the consistent values is \[0\.41\]"):
        check_factor_example(FactorExample(square_factor(4.0, right), _values(2.1)), "square")


def test_a_residual_of_the_wrong_size_is_caught():
    def error(this, v, H):
        if H is not None:
            H[0] = np.eye(2)
        return np.zeros(2)
    factor = gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(3, 0.1), [0], error)
    with pytest.raises(ContractFailure, match=r"short: residual has shape \(2,\); expected \(3,\)"):
        check_factor_example(FactorExample(factor, _values(1.0)), "short")


def test_class_level_check_names_the_factor_type_and_the_seed_that_failed():
    """`check_factor_contract` takes a FactorType class and names it and the seed on failure."""

    class BrokenPose(FactorType):
        name = "test.broken_pose"

        def build(self, ctx, spec):  # pragma: no cover - never built
            raise NotImplementedError

        @classmethod
        def example(cls, rng):
            x = gtsam.Pose3.Expmap(rng.normal(size=6))

            def error(this, v, H):
                p = v.atPose3(this.keys()[0])
                if H is not None:
                    H[0] = np.eye(6)  # ignores the inverse right Jacobian of Logmap
                return gtsam.Pose3.Logmap(x.between(p))
            values = gtsam.Values()
            values.insert(0, x)
            return FactorExample(gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(6, 0.01), [0], error), values)

    with pytest.raises(ContractFailure, match=r"test\.broken_pose \(seed 0\): Jacobian block 0 away from truth"):
        check_factor_contract(BrokenPose)
