"""Factors evaluated many at a time (docs/plugin_guide.md#vectorized-factors).

A plugin writes ONE residual function for N factor instances at once, on numpy arrays with a leading
axis N, and adds them with `ctx.add_vectorized`. fusionkit then
- linearizes all instances of the entry in one call of that function per solver iteration: its batch
  LM/GN, checks, marginals and reports (`GraphEvaluator`, graph/evaluator.py) and its iSAM2 and fixed-lag
  smoother (solve/linear_containers.py), and
- wraps each instance as a `gtsam.CustomFactor` for GTSAM's own callers (Dogleg, gtsam.Marginals) and the
  factor contract suite: the instances of one entry share their evaluations (`InstanceCache`), a lone
  factor (`instance_factor`) calls the function at N = 1.

Variables reach the function in these array forms (leading axis N):
    pose3 (N, 4, 4) homogeneous; pose2 (N, 3) [x, y, theta]; rot3 (N, 3, 3); scalar (N,);
    point3, point2, velocity3, vectorD (N, D); imu_bias (N, 6) [accelerometer, gyroscope]; a plugin's
    variable type its `VarType.to_array` form.
Jacobians are with respect to GTSAM's local coordinates: right perturbations X Exp(d) of poses and
rotations, additive for vectors; one (N, dim, d_j) array per variable.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import gtsam
import numpy as np

from ..errors import SolverError
from .passes import pass_token
from .variables import VarType

Function = Callable[[list[np.ndarray], dict[str, np.ndarray], bool], Any]
NUMERICAL_STEP = 1e-6


# --- array forms of the variable types (VarType.to_array, read_table, retract_array) -------------------
class ValueReader:
    """Reads variables of one gtsam.Values in array form; a type with a table read (poses: one C++ call for
    all of them) reads its table once, shared by every group read at these values."""

    def __init__(self, values: gtsam.Values):
        self.values = values
        self._tables: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def read(self, vartype: VarType, keys: np.ndarray) -> np.ndarray:
        """The values of `keys` (N,) in their array form (N, ...)."""
        if vartype.read_table is not None:
            if vartype.name not in self._tables:
                self._tables[vartype.name] = vartype.read_table(self.values)
            stored, table = self._tables[vartype.name]
            return table[np.searchsorted(stored, keys)]
        unique, inverse = np.unique(keys, return_inverse=True)
        arrays = np.array([vartype.to_array(vartype.read(self.values, int(k))) for k in unique])
        return arrays[inverse]

    def variables(self, types: tuple[VarType, ...], keys: np.ndarray) -> list[np.ndarray]:
        """The variables of N factors, keys (N, k) of the types `types`: one array per variable slot."""
        return [self.read(t, keys[:, j]) for j, t in enumerate(types)]


# --- the residual ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class VectorizedResidual:
    """A residual of `dim` rows over variables of the types `variables`, for N instances at once.

    `function(x, data, jacobians)`: `x` one array per variable (forms in the module docstring),
    `data` the instances' measurements {name: (N, ...)}; returns the residuals (N, dim), and with
    `jacobians=True` a pair (residuals, [d residual / d variable j, (N, dim, d_j)]).
    `jacobians="numerical"` at construction: the function only ever returns residuals and fusionkit
    takes central differences on the manifold (2 x total variable dimension calls, each vectorized)."""

    name: str
    variables: tuple[VarType, ...]
    dim: int
    function: Function
    jacobians: str = "analytic"

    def __post_init__(self):
        if self.jacobians not in ("analytic", "numerical"):
            raise ValueError(f"{self.name}: jacobians must be 'analytic' or 'numerical', not {self.jacobians!r}")

    def evaluate(self, x: list[np.ndarray], data: dict[str, np.ndarray], jacobians: bool):
        """Residuals (N, dim), or (residuals, Jacobians) with `jacobians`. A function that raises ValueError
        (variables outside the model's domain, e.g. a cable attachment inside its pulley's circle) stops the
        solve with a SolverError naming the residual."""
        try:
            if self.jacobians == "analytic":
                return self.function(x, data, jacobians)
            r = self.function(x, data, False)
            if not jacobians:
                return r
            return r, [self._numerical(x, data, j) for j in range(len(x))]
        except ValueError as exc:
            raise SolverError(f"{self.name}: {exc}: the estimate left the model's domain (check the initial "
                              "values and the sigmas)") from None

    def _numerical(self, x: list[np.ndarray], data: dict[str, np.ndarray], j: int) -> np.ndarray:
        vartype = self.variables[j]
        n = len(x[j])
        columns = []
        for a in range(vartype.dim):
            d = np.zeros((n, vartype.dim))
            d[:, a] = NUMERICAL_STEP
            plus, minus = list(x), list(x)
            plus[j], minus[j] = vartype.retract_array(x[j], d), vartype.retract_array(x[j], -d)
            columns.append((self.function(plus, data, False) - self.function(minus, data, False))
                           / (2 * NUMERICAL_STEP))
        return np.stack(columns, axis=-1)


def _slice(data: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
    return {name: array[i:i + 1] for name, array in data.items()}


class InstanceCache:
    """Serves N factors of one residual that GTSAM's own solvers (Dogleg, gtsam.Marginals, GTSAM's
    optimizers) call one at a time as CustomFactors: the first call at new values evaluates all N at once
    (when the values hold all their variables) and keeps the results with the variables they hold for;
    every other factor called at the same values finds its row there. A factor whose variables differ
    from the kept ones, with values lacking some of the N factors' variables, is evaluated alone (N = 1),
    as is a lone factor (reading all N at once extracts every pose of the values)."""

    def __init__(self, residual: VectorizedResidual, keys: np.ndarray, data: dict[str, np.ndarray]):
        self.residual, self.keys, self.data = residual, keys, data
        self.unique_keys = [int(k) for k in np.unique(keys)]
        self.held: list[np.ndarray] | None = None  # the variables (N, ...) of the kept results
        self.r = self.jacobians = None
        self.token: object | None = None  # the evaluation pass (graph/passes.py) the kept results are of

    def factor(self, row: int, noise: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
        """Factor `row` as a gtsam.CustomFactor."""
        def error(this: gtsam.CustomFactor, v: gtsam.Values, H) -> np.ndarray:
            r, jac = self.evaluate(row, v, H is not None)
            for j, block in enumerate(jac or ()):
                H[j] = block
            return r

        return gtsam.CustomFactor(noise, [int(k) for k in self.keys[row]], error)

    def evaluate(self, row: int, values: gtsam.Values, jacobians: bool):
        """(residual (dim,), [Jacobian blocks (dim, d_j)] or None) of factor `row` at `values`. Inside a pass of
        fusionkit's evaluator over these very values (pass_token) the first call evaluates all N (with Jacobians
        only when the pass linearizes) and the others read their row without reading a variable."""
        token = pass_token(values)
        if token is not None and len(self.keys) > 1:
            if (token is not self.token or (jacobians and self.jacobians is None)) and \
                    all(values.exists(k) for k in self.unique_keys):
                self._evaluate_all(values, jacobians)
                self.token = token
            if token is self.token:
                return self._row(row, jacobians)
        types = self.residual.variables
        x = [t.to_array(t.read(values, int(k)))[None] for t, k in zip(types, self.keys[row])]
        if len(self.keys) > 1 and not self._holds(row, x, jacobians) and \
                all(values.exists(k) for k in self.unique_keys):
            self._evaluate_all(values, True)
        if self._holds(row, x, jacobians):
            return self._row(row, jacobians)
        alone = self.residual.evaluate(x, _slice(self.data, row), jacobians)
        r, jac = alone if jacobians else (alone, None)
        return np.asarray(r, dtype=float)[0], ([B[0] for B in self._blocks(jac)] if jacobians else None)

    def _row(self, row: int, jacobians: bool):
        """Factor `row`'s kept residual and, when asked, Jacobian blocks."""
        return self.r[row], ([J[row] for J in self.jacobians] if jacobians else None)

    def _blocks(self, jac) -> list[np.ndarray]:
        """Jacobians as (N, dim, d_j) float arrays (what a CustomFactor's H takes, row by row)."""
        return [np.asarray(J, dtype=float).reshape(-1, self.residual.dim, t.dim)
                for J, t in zip(jac, self.residual.variables)]

    def _evaluate_all(self, values: gtsam.Values, jacobians: bool) -> None:
        self.held = ValueReader(values).variables(self.residual.variables, self.keys)
        out = self.residual.evaluate(self.held, self.data, jacobians)
        r, jac = out if jacobians else (out, None)
        self.r = np.asarray(r, dtype=float).reshape(len(self.keys), -1)
        self.jacobians = self._blocks(jac) if jacobians else None
        self.token = None  # kept for these values (held), whichever pass

    def _holds(self, row: int, x: list[np.ndarray], jacobians: bool = False) -> bool:
        return self.held is not None and (self.jacobians is not None or not jacobians) and \
            all(np.array_equal(h[row], xi[0]) for h, xi in zip(self.held, x))


def instance_factor(residual: VectorizedResidual, noise: gtsam.noiseModel.Base, keys, data_i: dict[str, np.ndarray]
                    ) -> gtsam.CustomFactor:
    """One factor as a gtsam.CustomFactor: the function at N = 1 (`data_i` arrays of length 1)."""
    return InstanceCache(residual, np.asarray([keys], dtype=np.int64), data_i).factor(0, noise)


# --- many instances: whitening, kernels, linear factors -----------------------------------------------
class VectorizedGroup:
    """The instances one entry added with one call: keys (N, k), data {name: (N, ...)}, sigmas (N, dim)
    and the entry's robust kernel (None or a gtsam mEstimator)."""

    def __init__(self, residual: VectorizedResidual, keys: np.ndarray, data: dict[str, np.ndarray],
                 sigmas: np.ndarray, kernel):
        self.residual = residual
        self.keys = keys
        self.data = data
        self.sigmas = sigmas
        self.kernel = kernel

    def subset(self, rows: np.ndarray) -> "VectorizedGroup":
        if len(rows) == len(self.keys) and np.array_equal(rows, np.arange(len(rows))):
            return self
        return VectorizedGroup(self.residual, self.keys[rows], {k: v[rows] for k, v in self.data.items()},
                               self.sigmas[rows], self.kernel)

    def _weights(self, whitened: np.ndarray) -> np.ndarray:
        """sqrt of the kernel's weight at each instance's whitened norm (GTSAM's Robust.reweight)."""
        if self.kernel is None:
            return np.ones(len(whitened))
        norms = np.linalg.norm(whitened, axis=1)
        return np.sqrt([self.kernel.weight(float(d)) for d in norms])

    def residuals(self, reader: ValueReader) -> np.ndarray:
        """Unwhitened residuals (N, dim)."""
        r = self.residual.evaluate(reader.variables(self.residual.variables, self.keys), self.data, False)
        return np.asarray(r, dtype=float).reshape(len(self.keys), self.residual.dim)

    def errors(self, reader: ValueReader) -> np.ndarray:
        """Each instance's error as GTSAM's NoiseModelFactor.error: 0.5 |r/sigma|^2, or the kernel's loss."""
        whitened = self.residuals(reader) / self.sigmas
        if self.kernel is None:
            return 0.5 * np.einsum("ij,ij->i", whitened, whitened)
        return np.array([self.kernel.loss(float(d)) for d in np.linalg.norm(whitened, axis=1)])

    def linear_factors(self, reader: ValueReader) -> list[gtsam.JacobianFactor]:
        """Whitened Jacobian factors of all instances, linearized in one call of the residual."""
        r, jac = self.residual.evaluate(reader.variables(self.residual.variables, self.keys), self.data, True)
        n = len(self.keys)
        r = np.asarray(r, dtype=float).reshape(n, -1)
        w = self._weights(r / self.sigmas)[:, None] / self.sigmas
        b = -(r * w)
        blocks = [np.asfortranarray(np.asarray(J, dtype=float).reshape(n, self.residual.dim, -1) * w[:, :, None])
                  for J in jac]
        unit = gtsam.noiseModel.Unit.Create(self.residual.dim)
        keys = self.keys.tolist()
        if len(blocks) == 1:
            return [gtsam.JacobianFactor(k[0], A, bi, unit) for k, A, bi in zip(keys, blocks[0], b)]
        if len(blocks) == 2:
            return [gtsam.JacobianFactor(k[0], A0, k[1], A1, bi, unit)
                    for k, A0, A1, bi in zip(keys, blocks[0], blocks[1], b)]
        if len(blocks) == 3:
            return [gtsam.JacobianFactor(k[0], A0, k[1], A1, k[2], A2, bi, unit)
                    for k, A0, A1, A2, bi in zip(keys, blocks[0], blocks[1], blocks[2], b)]
        raise ValueError(f"{self.residual.name}: more than three variables are linearized per instance "
                         "(GaussianFactor bindings take at most three blocks)")
