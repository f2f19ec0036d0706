"""The factor contract: every factor type, built-in or installed, must satisfy it.

1. zero residual at the consistent values of its `example()`;
2. shapes: the linearized factor has `dim()` rows and one block per key of the right width;
3. analytic Jacobians equal central differences to tight tolerance;
4. the same holds at perturbed values (away from truth), and the residual stays finite.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from .jacobians import numerical_jacobians


class ContractFailure(AssertionError):
    """A factor broke the contract; the message says which clause and by how much."""


@dataclass
class FactorExample:
    """A factor and values at which its (unwhitened) residual is zero. `perturbation` is the
    standard deviation of the tangent-space step to the "away from truth" check: keep it inside
    the region where the model is defined (a statics factor whose cables go slack 3 degrees away
    needs a smaller one)."""

    factor: gtsam.NonlinearFactor
    values: gtsam.Values
    perturbation: float = 0.05


def _blocks(factor: gtsam.NonlinearFactor, values: gtsam.Values) -> list[np.ndarray]:
    lin = factor.linearize(values)
    A = lin.jacobian()[0]
    dims = [values.zeroVectors().at(k).shape[0] for k in factor.keys()]
    if A.shape != (factor.dim(), sum(dims)):
        raise ContractFailure(f"linearized Jacobian is {A.shape}; expected ({factor.dim()}, {sum(dims)})")
    return np.split(A, np.cumsum(dims)[:-1], axis=1)


def check_factor_example(example: FactorExample, name: str = "factor", rtol: float = 1e-5,
                         atol: float = 1e-6, rng: np.random.Generator | None = None) -> None:
    """Check one example; raise ContractFailure naming `name` and the clause that failed."""
    rng = rng or np.random.default_rng(0)
    f, values = example.factor, example.values
    err = np.asarray(f.unwhitenedError(values))
    if err.shape != (f.dim(),):
        raise ContractFailure(f"{name}: residual has shape {err.shape}; expected ({f.dim()},)")
    if np.max(np.abs(err), initial=0.0) > 1e-9:
        raise ContractFailure(f"{name}: residual at the consistent values is {err} (expected 0)")
    zero = values.zeroVectors()
    perturbed = gtsam.VectorValues()
    for key in f.keys():
        perturbed.insert(key, example.perturbation * rng.standard_normal(zero.at(key).shape[0]))
    for label, at in (("at truth", values), ("away from truth", values.retract(perturbed))):
        if not np.all(np.isfinite(f.whitenedError(at))):
            raise ContractFailure(f"{name}: non-finite residual {label}")
        for i, (analytic, numeric) in enumerate(zip(_blocks(f, at), numerical_jacobians(f, at))):
            if not np.allclose(analytic, numeric, rtol=rtol, atol=atol):
                worst = np.max(np.abs(analytic - numeric))
                raise ContractFailure(f"{name}: Jacobian block {i} {label} differs from central "
                                      f"differences by {worst:.3g}")


def check_factor_contract(factor_type: type, seeds: tuple[int, ...] = (0, 1, 2)) -> None:
    """Run the contract over examples of `factor_type` drawn with several seeds."""
    for seed in seeds:
        rng = np.random.default_rng(seed)
        check_factor_example(factor_type.example(rng), f"{factor_type.name} (seed {seed})", rng=rng)


def check_installed_factor_types() -> list[str]:
    """Run the contract over every registered factor type; return the names checked."""
    from ..plugins import registry
    reg = registry()
    names = reg.names("factor_types")
    for name in names:
        check_factor_contract(reg.get("factor_types", name))
    return names
