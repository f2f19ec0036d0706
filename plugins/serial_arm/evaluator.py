"""The marker factors of one config entry evaluated together (docs/models/serial_arm.md#speed).

GTSAM calls each `CustomFactor` on its own, and a solver's linearization calls every factor of the
entry at the same parameter values. The entry's factors therefore share one evaluator: the first
factor called at parameter values not seen before has every factor of the entry (those whose
variables the values hold) evaluated in one vectorized pass (batch.py), and the others read their
residual and Jacobians from it. A factor's cached result is used only when every one of its
variables equals, bit for bit, the values it was computed at (its readers return the raw bytes), or
when it was computed in the current pass of fusionkit's evaluator over this very Values object
(`pass_token`: then nothing is read again); anything else is computed again, so the result is always
the factor's own (incremental solvers that add one factor at a time get it evaluated alone).
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import pass_token

from . import batch
from .chain import SerialChain
from .kinematics import Layout, Parameters

KINDS = ("pose", "position", "relative")


def _read_pose3(values: gtsam.Values, key: int) -> bytes:
    return values.atPose3(key).matrix().tobytes()


def _read_point3(values: gtsam.Values, key: int) -> bytes:
    return values.atPoint3(key).tobytes()


def _read_scalar(values: gtsam.Values, key: int) -> float:
    return values.atDouble(key)


def _read_vector(values: gtsam.Values, key: int) -> bytes:
    return values.atVector(key).tobytes()


class EntryEvaluator:
    """Residuals and Jacobians of an entry's marker factors. Factor i's variables are `keys[i]`: its
    joint vector (two for `relative`), then the layout's variables. `measured`: per factor, the
    inverse measured pose (pose, relative; (N, 4, 4)) or the measured position ((N, 3))."""

    def __init__(self, chain: SerialChain, layout: Layout, kind: str, measured: np.ndarray, keys: list[list[int]]):
        assert kind in KINDS
        self.chain, self.layout, self.kind = chain, layout, kind
        self.measured = np.asarray(measured, float)
        self.keys = [list(k) for k in keys]
        self.joints = 2 if kind == "relative" else 1
        tool = {"pose3": _read_pose3, "point3": _read_point3}.get(layout.tool)
        self.readers = ([_read_vector] * self.joints + [_read_pose3] * layout.base + ([tool] if tool else [])
                        + [_read_scalar] * len(layout.offsets) + [_read_vector] * len(layout.placements)
                        + [_read_scalar] * len(layout.compliances) + [_read_vector] * len(layout.mass_compliances))
        self.reader_of = {k: r for ks in self.keys for k, r in zip(ks, self.readers)}
        tool_shape = {"pose3": (4, 4), "point3": (3,)}.get(layout.tool)
        self.shapes = ([(chain.n,)] * self.joints + [(4, 4)] * layout.base + ([tool_shape] if tool_shape else [])
                       + [None] * len(layout.offsets) + [(len(axes),) for _, axes in layout.placements]
                       + [None] * len(layout.compliances) + [(len(layout.lumped),)] * len(layout.mass_compliances))
        n = len(self.keys)
        # variables every factor shares (static parameters): a change in them means a new linearization
        self.shared = [p for p in range(self.joints, len(self.readers))
                       if n and all(ks[p] == self.keys[0][p] for ks in self.keys)]
        dim = 3 if kind == "position" else 6
        widths = [chain.n] * self.joints + layout.widths
        self.e = np.zeros((n, dim))
        self.H = [np.zeros((n, dim, w)) for w in widths]
        self.fingerprints: list[tuple | None] = [None] * n
        self.last_shared: tuple | None = None
        self.token: object | None = None  # the evaluation pass whose values every present factor is at
        self.present = np.zeros(n, bool)  # the factors evaluated in that pass
        self.with_jacobians = False       # whether that pass computed their Jacobians too

    def error(self, i: int, this, values: gtsam.Values, H) -> np.ndarray:
        """The CustomFactor callback of factor i (bind i with functools.partial)."""
        token = pass_token(values)
        if token is not None:
            if token is not self.token or (H is not None and not self.with_jacobians):
                self._evaluate_pass(values, token, H is not None)
            if not self.present[i]:
                token = None
        if token is None:
            fp = tuple([read(values, k) for read, k in zip(self.readers, self.keys[i])])
            if fp != self.fingerprints[i]:
                self._refresh(i, fp, values)
        if H is not None:
            for j, block in enumerate(self.H):
                H[j] = block[i]
        return self.e[i]

    def _evaluate_pass(self, values: gtsam.Values, token: object, jacobians: bool) -> None:
        """Every factor whose variables `values` holds, at once, for the rest of the evaluation pass `token` (the
        Jacobians only when the pass linearizes): each variable read once, no fingerprints kept."""
        read = {k: r(values, k) for k, r in self.reader_of.items() if values.exists(k)}
        self.present = np.ones(len(self.keys), bool) if len(read) == len(self.reader_of) else \
            np.array([all(k in read for k in ks) for ks in self.keys], bool)
        idx = np.flatnonzero(self.present)
        columns = [[read[self.keys[idx[0]][p]]] if p in self.shared else [read[self.keys[i][p]] for i in idx]
                   for p in range(len(self.readers))] if len(idx) else []
        if len(idx):
            self._compute(idx, columns, jacobians)
        self.token, self.with_jacobians = token, jacobians
        for i in idx:
            self.fingerprints[i] = None  # computed for this pass only

    def _refresh(self, i: int, fp: tuple, values: gtsam.Values) -> None:
        shared = tuple(fp[p] for p in self.shared)
        if self.shared and shared != self.last_shared:  # new parameter values: evaluate every factor
            self.last_shared = shared
            self._evaluate_present(values)
        if fp != self.fingerprints[i]:
            self._compute([i], [[v] for v in fp], True, [fp])

    def _evaluate_present(self, values: gtsam.Values) -> None:
        """Every factor whose variables `values` holds and whose cached result is not at them."""
        read = {k: r(values, k) for k, r in self.reader_of.items() if values.exists(k)}
        stale, fps = [], []
        for i, ks in enumerate(self.keys):
            if all(k in read for k in ks):
                fp = tuple([read[k] for k in ks])
                if fp != self.fingerprints[i]:
                    stale.append(i)
                    fps.append(fp)
        if stale:
            self._compute(stale, [list(c) for c in zip(*fps)], True, fps)

    def _column(self, raw: list, p: int, stacked: bool = False):
        """Variable p's value for the samples from its raw readings: one value when every sample shares it, else
        stacked."""
        shape = self.shapes[p]
        if not stacked and (p in self.shared or len(raw) == 1):
            return raw[0] if shape is None else np.frombuffer(raw[0]).reshape(shape)
        if shape is None:
            return np.array(raw)
        return np.frombuffer(b"".join(raw)).reshape((len(raw),) + shape)

    def _parameters(self, columns: list[list]) -> Parameters:
        lay, p = self.layout, self.joints
        out = Parameters()
        if lay.base:
            out.base, p = self._column(columns[p], p), p + 1
        if lay.tool:
            tool = self._column(columns[p], p)
            if lay.tool == "point3":
                point, tool = tool, np.zeros(np.shape(tool)[:-1] + (4, 4))
                tool[..., :3, :3] = np.eye(3)
                tool[..., :3, 3] = point
                tool[..., 3, 3] = 1.0
            out.tool, p = tool, p + 1
        groups = []
        for count in (len(lay.offsets), len(lay.placements), len(lay.compliances), len(lay.mass_compliances)):
            groups.append([self._column(columns[p + j], p + j) for j in range(count)])
            p += count
        out.offsets, out.placements, out.compliances, out.mass_compliances = groups
        return out

    def _compute(self, idx, columns: list[list], jacobians: bool, fps: list[tuple] | None = None) -> None:
        """Residuals (and Jacobians) of factors `idx` from their variables' raw readings `columns` (per variable,
        per factor; a shared variable's once); `fps`: their fingerprints, kept to serve later calls."""
        params = self._parameters(columns)
        q = [self._column(columns[j], j, stacked=True) for j in range(self.joints)]
        if self.kind == "relative":
            a = batch.marker_poses(self.chain, self.layout, q[0], params, jacobians)
            b = batch.marker_poses(self.chain, self.layout, q[1], params, jacobians)
            e, blocks = batch.relative_residuals(a, b, self.measured[idx])
        else:
            poses = batch.marker_poses(self.chain, self.layout, q[0], params, jacobians)
            residuals = batch.pose_residuals if self.kind == "pose" else batch.position_residuals
            e, blocks = residuals(poses, self.measured[idx])
        self.e[idx] = e
        for H, block in zip(self.H, blocks or ()):
            H[idx] = block
        if fps is not None:  # a call outside the pass (another Values) overwrote rows the pass served
            self.token = None
        for i, fp in zip(idx, fps or ()):
            self.fingerprints[i] = fp
