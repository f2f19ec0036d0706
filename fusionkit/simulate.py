"""`fusionkit simulate`: write a simulator's dataset in the documented formats, its truth, the
robot descriptions and a runnable config when the simulator provides them (all into one folder,
atomically; no empty subfolder)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from .config.loader import RunConfig, load_config
from .config.overrides import apply_override
from .config.yamlio import Document
from .data.files import write_csv_stream, write_tum
from .data.rosbag_writer import write_bag
from .errors import ConfigError
from .plugins import registry
from .report.writer import atomic_directory


def _bag_name(ros: str) -> str:
    return "data/recording.bag" if ros == "ros1" else "data/recording"


def write_dataset(scenario: str, out: Path, overrides: list[str], seed: int = 0, bag: str | None = None) -> list[Path]:
    """`bag` (ros1 | ros2): the data as one ROS bag (topic /<stream>, the truth trajectories also as
    /truth/<robot>) read by a `rosbag` source, instead of one CSV or TUM file per stream."""
    reg = registry()
    cls = reg.get("simulators", scenario)
    if cls is None:
        raise ConfigError(reg.unknown("simulators", scenario) + " (a third-party scenario needs its package "
                          "installed)")
    params: dict = {}
    for assignment in overrides:
        apply_override(params, assignment)
    params = cls.resolve(params, Document(params, Path(f"<simulate {scenario}>")))
    sim = cls()
    data = sim.simulate(params, np.random.default_rng(seed))
    written: list[Path] = []
    with atomic_directory(out, "simulate") as tmp:
        for sub in ("data", "truth", "robots"):
            (tmp / sub).mkdir()
        sources = []
        if bag:
            topics = {f"/{name}": stream for name, stream in data.streams.items()}
            truth_topics = {f"/truth/{robot}": traj for robot, traj in (data.truth_trajectories or {}).items()}
            write_bag(tmp / _bag_name(bag), {**topics, **truth_topics}, bag)
            sources.append({"type": "rosbag", "path": _bag_name(bag), "topics": {t: s.name for t, s in topics.items()}})
        for name, stream in ({} if bag else data.streams).items():
            if stream.is_pose:
                write_tum(tmp / "data" / f"{name}.tum", stream)
                sources.append({"type": "tum", "name": name, "path": f"data/{name}.tum"})
            else:
                write_csv_stream(tmp / "data" / f"{name}.csv", stream)
                sources.append({"type": "csv", "name": name, "path": f"data/{name}.csv"})
        truth: dict = {}
        for robot, traj in (data.truth_trajectories or {}).items():
            write_tum(tmp / "truth" / f"{robot}.tum", traj)
            truth.setdefault("trajectories", {})[robot] = f"truth/{robot}.tum"
        for robot, families in (data.truth_states or {}).items():  # other state families: CSV, t + components
            for family, stream in families.items():
                write_csv_stream(tmp / "truth" / f"{robot}.{family}.csv", stream)
                truth.setdefault("states", {}).setdefault(robot, {})[family] = f"truth/{robot}.{family}.csv"
        if data.truth_calibration:
            (tmp / "truth" / "calibration.yaml").write_text(yaml.safe_dump(
                {"fusionkit_calibration": 1, "robots": data.truth_calibration}, sort_keys=False))
            truth["calibration"] = "truth/calibration.yaml"
        for robot, desc in sim.robots(params).items():
            (tmp / "robots" / f"{robot}.yaml").write_text(yaml.safe_dump(desc, sort_keys=False))
        config = sim.config(params)
        if config:
            config = {"name": f"{scenario.replace('.', '_')}_sim", **config, "sources": sources,
                      "truth": {**config.get("truth", {}), **truth}}  # the simulator's settings (align) kept
            (tmp / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
        for sub in ("data", "truth", "robots"):
            if not any((tmp / sub).iterdir()):
                (tmp / sub).rmdir()
        written = [p.relative_to(tmp) for p in tmp.rglob("*") if p.is_file()]
    return [out / p for p in written]


@contextmanager
def simulated_config(scenario: str, params: dict, seed: int = 0,
                     edit: Callable[[dict], None] | None = None) -> Iterator[RunConfig]:
    """The validated config a simulator writes for its own data, with the data generated
    in-process (a `simulate` source) and its robot descriptions in a temporary folder that lives
    as long as the context; `edit(config)` may change the config dict first. For experiments and
    benchmarks that run many simulated datasets without writing them."""
    sim = registry().get("simulators", scenario)()
    full = sim.resolve(params, Document(params, Path(f"<simulate {scenario}>")))
    config = {"name": f"{scenario.replace('.', '_')}_{seed}", **sim.config(full),
              "sources": [{"type": "simulate", "scenario": scenario, "seed": seed, "params": params}]}
    if edit:
        edit(config)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "robots").mkdir()
        for robot, desc in sim.robots(full).items():
            (folder / "robots" / f"{robot}.yaml").write_text(yaml.safe_dump(desc, sort_keys=False))
        (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
        yield load_config(folder / "config.yaml")
