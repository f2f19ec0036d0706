"""Source `uwb.labyrinth`: the text format of "The Labyrinth Dataset" (TU Chemnitz, CC BY-SA 4.0):
one measurement per line, the first word its type.

    range2    t range variance anchor_x anchor_y anchor_id snr
    odom2diff t v_right v_left v_lateral wheel_distance ... covariances
    point2    t x y ...        (ground truth, in <prefix>_GT.txt)

Streams: `ranges` (t, anchor, range: one row per range, `anchor` its id), `wheels` (t, v_right,
v_left in m/s). Truth: the trajectory of robot `robot` (positions, heading 0) and the anchors'
positions as the point2 parameter `anchor` of robot `anchors`, in the order of their sorted ids
(which `ids` of uwb.range must list in the same order).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusionkit.api import NAME_SCHEMA as NAME, Source, SourceOutput, Spec, Stream, pose_stream



def _rows(path: Path, kind: str) -> np.ndarray:
    rows = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            words = line.split()
            if words and words[0] == kind:
                try:
                    rows.append([float(w) for w in words[1:]])
                except ValueError:
                    raise ValueError(f"{path}:{n}: expected numbers after {kind!r}") from None
    if not rows:
        raise ValueError(f"{path}: no {kind!r} lines")
    return np.array(rows)


def read_labyrinth(folder: Path, prefix: str = "Indoor_UWB"):
    """(ranges (K, 3): t, anchor id, range; anchors {id: (x, y)}; wheels (M, 3): t, v_right, v_left;
    truth (N, 3): t, x, y)."""
    data = Path(folder) / f"{prefix}_Input.txt"
    ranges = _rows(data, "range2")
    odom = _rows(data, "odom2diff")
    truth = _rows(Path(folder) / f"{prefix}_GT.txt", "point2")
    anchors = {float(i): (float(x), float(y)) for x, y, i in ranges[:, 3:6]}
    return ranges[:, [0, 5, 1]], anchors, odom[:, :3], truth[:, :3]


class LabyrinthSource(Source):
    name = "uwb.labyrinth"
    summary = "The Labyrinth Dataset's text files: UWB ranges (range2), wheel speeds (odom2diff), truth (point2)"
    schema = {"type": "object", "properties": {"path": NAME, "prefix": {**NAME, "default": "Indoor_UWB"},
                                               "robot": {**NAME, "default": "robot"},
                                               "anchors": {**NAME, "default": "anchors"}},
              "required": ["path"], "additionalProperties": False}

    def stream_names(self, spec: Spec, base_dir: Path):
        return {"ranges": ("anchor", "range"), "wheels": ("v_right", "v_left")}

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        folder = Path(spec["path"]) if Path(spec["path"]).is_absolute() else base_dir / spec["path"]
        if not folder.is_dir():
            raise spec.error("path", f"folder not found: {folder}")
        try:
            ranges, anchors, wheels, truth = read_labyrinth(folder, spec["prefix"])
        except (OSError, ValueError) as exc:
            raise spec.error("path", str(exc)) from None
        ids = sorted(anchors)
        streams = {"ranges": Stream("ranges", ranges[:, 0], ("anchor", "range"), ranges[:, 1:], str(folder)),
                   "wheels": Stream("wheels", wheels[:, 0], ("v_right", "v_left"), wheels[:, 1:], str(folder))}
        poses = np.column_stack([truth[:, 1:], np.zeros((len(truth), 4)), np.ones(len(truth))])
        robot = spec["robot"]
        calibration = {spec["anchors"]: {"anchor": {"type": "point2",
                                                                   "values": [list(anchors[i]) for i in ids]}}}
        return SourceOutput(streams, {robot: pose_stream(robot, truth[:, 0], poses, str(folder))}, calibration)


SOURCES = [LabyrinthSource]
