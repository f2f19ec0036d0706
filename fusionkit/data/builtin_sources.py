"""Built-in sources: stream CSV, TUM trajectories, ROS 1/2 bags, and in-process simulation."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..hookspecs import hookimpl
from ..components import SourceOutput, Source, Spec
from .files import csv_has_time_column, read_csv_header, read_csv_stream, read_tum
from .recordings import concatenated
from .stream import POSE_COLUMNS

NAME = {"type": "string", "pattern": "^[A-Za-z_][A-Za-z0-9_./-]*$"}


def resolve(base_dir: Path, path: str) -> Path:
    p = Path(path)
    return p if p.is_absolute() else base_dir / p


def existing_files(spec: Spec, base_dir: Path, what: str = "file") -> list[Path]:
    """The entry's `path`, one file or a list of them (several recordings), resolved; a located error for one
    that is missing or a folder."""
    given = spec["path"]
    out = []
    for i, text in enumerate(given if isinstance(given, list) else [given]):
        key = ("path", i) if isinstance(given, list) else "path"
        path = resolve(base_dir, text)
        if path.is_dir():
            raise spec.error(key, f"{path} is a folder; expected a {what}")
        if not path.is_file():
            raise spec.error(key, f"{what} not found: {path}")
        out.append(path)
    return out


PATHS = {"oneOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}, "minItems": 1}],
         "description": "a file, or a list of files: recordings of the stream, one after the other in time"}


class CsvSource(Source):
    name = "csv"
    summary = ("stream CSV: header row, first column t (s), then named numeric columns (several files: recordings; "
               "`time: row` for static samples without time stamps: t = row number)")
    schema = {"type": "object", "properties": {"name": NAME, "path": PATHS,
                                               "columns": {"type": "array", "items": {"type": "string"}},
                                               "time": {"enum": ["column", "row"], "default": "column"}},
              "required": ["name", "path"], "additionalProperties": False}

    def stream_names(self, spec: Spec, base_dir: Path):
        path = existing_files(spec, base_dir)[0]
        return {spec["name"]: tuple(spec.get("columns") or read_csv_header(path, spec.get("time") == "row"))}

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        """`time: row`: a file without a `t` column numbers its rows 0, 1, ... (static samples: sample i of every
        such stream is the same configuration); with several files the numbering continues across them."""
        files = existing_files(spec, base_dir)
        indexed = spec.get("time") == "row"
        parts = [read_csv_stream(f, spec["name"], tuple(spec.get("columns", ())), indexed) for f in files]
        if indexed:
            after = None  # the last sample number so far
            for f, part in zip(files, parts):  # a numbered file's rows continue the previous files' numbering
                if not csv_has_time_column(f) and after is not None:
                    part.t = part.t + np.floor(after) + 1
                after = part.t[-1] if len(part.t) else after
        stream = concatenated(parts, files)
        return SourceOutput({stream.name: stream})


class TumSource(Source):
    name = "tum"
    summary = "TUM trajectory: t x y z qx qy qz qw per line (poses; several files: recordings)"
    schema = {"type": "object", "properties": {"name": NAME, "path": PATHS},
              "required": ["name", "path"], "additionalProperties": False}

    def stream_names(self, spec: Spec, base_dir: Path):
        existing_files(spec, base_dir)
        return {spec["name"]: POSE_COLUMNS}

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        files = existing_files(spec, base_dir)
        stream = concatenated([read_tum(f, spec["name"]) for f in files], files)
        return SourceOutput({stream.name: stream})


class RosbagSource(Source):
    name = "rosbag"
    summary = "ROS 1 (.bag) or ROS 2 bag: PoseStamped, Odometry, Imu, JointState topics -> streams"
    schema = {"type": "object",
              "properties": {"path": {"type": "string"},
                             "topics": {"type": "object", "minProperties": 1, "additionalProperties": NAME}},
              "required": ["path", "topics"], "additionalProperties": False}

    def stream_names(self, spec: Spec, base_dir: Path):
        from .rosbag_reader import topic_columns
        path = resolve(base_dir, spec["path"])
        if not path.exists():
            raise spec.error("path", f"bag not found: {path}")
        columns = topic_columns(path, list(spec["topics"]))
        return {spec["topics"][topic]: cols for topic, cols in columns.items()}

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        from .rosbag_reader import read_bag
        return SourceOutput(read_bag(resolve(base_dir, spec["path"]), dict(spec["topics"])))


class SimulateSource(Source):
    """Runs a registered simulator in-process: data the package makes itself, with its truth."""

    name = "simulate"
    summary = "in-process synthetic data from a registered simulator (streams + truth)"
    schema = {"type": "object",
              "properties": {"scenario": {"type": "string"}, "seed": {"type": "integer", "default": 0},
                             "params": {"type": "object", "default": {}}},
              "required": ["scenario"], "additionalProperties": False}

    def _simulator(self, spec: Spec):
        from ..plugins import registry
        reg = registry()
        cls = reg.get("simulators", spec["scenario"])
        if cls is None:
            raise spec.error("scenario", reg.unknown("simulators", spec["scenario"]))
        return cls(), cls.resolve(dict(spec["params"]), spec.doc, spec.path + ("params",))

    def check(self, spec: Spec, scope) -> None:
        self._simulator(spec)

    def stream_names(self, spec: Spec, base_dir: Path):
        sim, params = self._simulator(spec)
        return sim.stream_columns(params)

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        sim, params = self._simulator(spec)
        return sim.simulate(params, np.random.default_rng(spec["seed"]))


@hookimpl
def register_sources():
    return [CsvSource, TumSource, RosbagSource, SimulateSource]
