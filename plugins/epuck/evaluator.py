"""The IR factors of one config entry evaluated together (docs/models/epuck.md#speed).

GTSAM calls each `CustomFactor` on its own, and a linearization calls every factor at the same
values. The entry's factors share one evaluator: the first factor called at values it has not seen
computes every factor whose pose the values hold and whose cached result is not at them, in one
vectorized pass over all their readings (irfactor.IrModelContext.quantities); the others read their
residual and Jacobians from the cache. A cached result is used only when the factor's pose, gains
and offsets equal, bit for bit, those it was computed at, so a factor always gets its own result
(an incremental solver's new factor is computed with the few others its values changed).
"""

from __future__ import annotations

import gtsam
import numpy as np

from .irfactor import IrModelContext, Quantities, ReadingSet, assemble

FIELDS = ("sensor", "z", "kind", "threshold", "sigma_fixed")


class IrEntryEvaluator:
    """Factor i has readings `readings[i]` and keys [pose, its readings' gains..., offsets...] (each
    block present when `calibrated` says so)."""

    def __init__(self, model: IrModelContext, readings: list[ReadingSet], keys: list[list[int]],
                 calibrated: tuple[bool, bool]):
        self.model, self.keys, self.calibrated = model, [list(k) for k in keys], calibrated
        self.count = np.array([len(r.sensor) for r in readings])
        self.start = np.concatenate([[0], np.cumsum(self.count)[:-1]]).astype(int)
        self.all = ReadingSet(*(np.concatenate([getattr(r, f) for r in readings]) for f in FIELDS))
        self.rows = [r.rows(model.noise) for r in readings]
        self.by_pose: dict[int, list[int]] = {}
        for i, k in enumerate(self.keys):
            self.by_pose.setdefault(k[0], []).append(i)
        total = int(self.count.sum())
        self.cache = Quantities(np.zeros((3, total)), np.zeros((3, total)), np.zeros((3, total)),
                                np.zeros((3, total)), np.zeros((total, 3)))
        self.fingerprints: list[tuple | None] = [None] * len(self.keys)

    def error(self, i: int, this, values: gtsam.Values, H) -> np.ndarray:
        """The CustomFactor callback of factor i (bind i with functools.partial)."""
        fp = self._fingerprint(i, values)
        if fp != self.fingerprints[i]:
            self._refresh(values, i, fp)
        comp, local = self.rows[i]
        K = int(self.count[i])
        if H is None:
            return assemble(self.cache, comp, self.start[i] + local, local, K, False)
        e, Hp, Hg, Ho = assemble(self.cache, comp, self.start[i] + local, local, K, True)
        H[0] = Hp
        blocks = ([Hg] if self.calibrated[0] else []) + ([Ho] if self.calibrated[1] else [])
        for b, block in enumerate(blocks):
            for j in range(K):
                H[1 + b * K + j] = block[:, j:j + 1]
        return e

    def _fingerprint(self, i: int, values: gtsam.Values) -> tuple:
        keys = self.keys[i]
        p = values.atPose2(keys[0])
        return (p.x(), p.y(), p.theta()) + tuple(values.atDouble(k) for k in keys[1:])

    def _refresh(self, values: gtsam.Values, i: int, fp: tuple) -> None:
        """Compute factor i and every other factor whose pose `values` holds and whose cache is stale."""
        stale, fps = [i], [fp]
        for key in values.keys():
            for j in self.by_pose.get(key, ()):
                if j != i:
                    other = self._fingerprint(j, values)
                    if other != self.fingerprints[j]:
                        stale.append(j)
                        fps.append(other)
        self._compute(stale, fps)

    def _compute(self, factors: list[int], fps: list[tuple]) -> None:
        counts = self.count[factors]
        idx = np.concatenate([np.arange(self.start[j], self.start[j] + c) for j, c in zip(factors, counts)])
        pose = np.repeat(np.array([f[:3] for f in fps]), counts, axis=0)
        gain, offset = np.ones(len(idx)), np.zeros(len(idx))
        if self.calibrated[0]:
            gain = np.concatenate([f[3:3 + c] for f, c in zip(fps, counts)])
        if self.calibrated[1]:
            at = 3 + counts * self.calibrated[0]
            offset = np.concatenate([f[a:a + c] for f, a, c in zip(fps, at, counts)])
        subset = ReadingSet(*(getattr(self.all, f)[idx] for f in FIELDS))
        q = self.model.quantities(pose, subset, gain, offset)
        self.cache.e[:, idx], self.cache.de_dd[:, idx] = q.e, q.de_dd
        self.cache.de_dgain[:, idx], self.cache.de_doffset[:, idx] = q.de_dgain, q.de_doffset
        self.cache.dd_dpose[idx] = q.dd_dpose
        for j, f in zip(factors, fps):
            self.fingerprints[j] = f
