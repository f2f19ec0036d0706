"""Namespaced variable keys with a reverse map, so reports print `cam/pose[12]`, not integers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .variables import VarType

INDEX_BITS = 40
STATE, STATIC, TIME_VARYING = "state", "static", "time_varying"
MEASUREMENT = "measurement_time"  # a sample's state at its own time (fusionkit/time_offset): keys, no variables


@dataclass(frozen=True)
class Family:
    """A family of variables of one robot: per-state, static, time-varying (one per state), or
    measurement-time (keys that stand for a state at a sample's time; no variables: fusionkit/time_offset)."""

    id: int
    robot: str
    name: str
    vartype: VarType
    kind: str
    indexed: bool = True
    elements: tuple[str, ...] | None = None  # names of the indices (a parameter's `Parameter.elements`)
    shown: str = ""  # the name printed, if not `name` (an element's own time-varying family: `offset[elbow_joint]`)

    def key(self, index: int = 0) -> int:
        return (self.id << INDEX_BITS) | int(index)

    def keys(self, indices) -> list[int]:
        """key(i) for every i of `indices` (a sequence or array of ints)."""
        return ((self.id << INDEX_BITS) | np.asarray(indices, dtype=np.int64)).tolist()

    def label(self, index: int | None = None) -> str:
        """`cam/pose[12]`, `arm/joint_offsets[elbow_joint]` (named elements), `cam/vo_scale` (no index)."""
        base = f"{self.robot}/{self.shown or self.name}"
        if index is None:
            return base
        return f"{base}[{self.elements[index] if self.elements and 0 <= index < len(self.elements) else index}]"


class KeyRegistry:
    """Declares families and turns keys back into names."""

    def __init__(self) -> None:
        self._families: dict[tuple[str, str], Family] = {}
        self._by_id: dict[int, Family] = {}

    def family(self, robot: str, name: str, vartype: VarType, kind: str,
               indexed: bool = True, elements: tuple[str, ...] | None = None, shown: str = "") -> Family:
        """Declare (or fetch) a family; declaring it twice with another type is an error. `elements` and
        `shown`: how labels name its indices and itself (Family), taken from the first declaration."""
        found = self._families.get((robot, name))
        if found is not None:
            if found.vartype.name != vartype.name or found.kind != kind:
                raise ValueError(
                    f"variable {robot}/{name} declared as {found.kind} {found.vartype.name} "
                    f"and again as {kind} {vartype.name}")
            return found
        fam = Family(len(self._families) + 1, robot, name, vartype, kind, indexed, elements, shown)
        self._families[(robot, name)] = fam
        self._by_id[fam.id] = fam
        return fam

    def get(self, robot: str, name: str) -> Family | None:
        return self._families.get((robot, name))

    def families(self) -> list[Family]:
        return list(self._families.values())

    def group(self, keys) -> list[tuple[Family, list[int]]]:
        """`keys` by family (in family order), each family's keys in ascending order."""
        a = np.sort(np.asarray(keys, dtype=np.uint64))
        ids = a >> np.uint64(INDEX_BITS)
        cuts = np.flatnonzero(np.diff(ids)) + 1
        return [(self._family_by_id(int(part[0] >> np.uint64(INDEX_BITS))), part.tolist())
                for part in np.split(a, cuts) if len(part)]

    def _family_by_id(self, family_id: int) -> Family:
        fam = self._by_id.get(family_id)
        if fam is None:
            raise KeyError(family_id << INDEX_BITS)
        return fam

    def decode(self, key: int) -> tuple[Family, int]:
        fam = self._by_id.get(int(key) >> INDEX_BITS)
        if fam is None:
            raise KeyError(key)
        return fam, int(key) & ((1 << INDEX_BITS) - 1)

    def name_of(self, key: int) -> str:
        """`cam/pose[12]` for states and indexed parameters, `cam/vo_scale` for single ones."""
        try:
            fam, index = self.decode(key)
        except KeyError:
            return f"<unknown key {key}>"
        return fam.label(index if fam.indexed else None)
