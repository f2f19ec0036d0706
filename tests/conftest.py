"""Shared helpers: configs and data files in a temporary folder, and a registry with extra plugins.
The research code (research/: experiments, baselines, reference models, external data; not installed)
is imported as `research.<module>`: the repository root goes on sys.path, the benchmark folder does not."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import gtsam
import numpy as np
import pytest
import yaml

import fusionkit.plugins
from fusionkit.data.files import write_csv_stream, write_tum
from fusionkit.data.stream import Stream, pose_stream

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # research/ (not installed) as `research.<module>`


class Workspace:
    """A temporary folder to write data files and configs into (paths in configs are relative)."""

    def __init__(self, folder: Path):
        self.folder = folder

    def poses(self, name: str, t: np.ndarray, poses: list[gtsam.Pose3] | np.ndarray) -> dict:
        """Write a TUM file `name.tum`; return the `sources:` entry that reads it."""
        write_tum(self.folder / f"{name}.tum", pose_stream(name, np.asarray(t, float), poses))
        return {"type": "tum", "name": name, "path": f"{name}.tum"}

    def columns(self, name: str, t: np.ndarray, **columns: np.ndarray) -> dict:
        """Write a stream CSV `name.csv` (t plus the named columns); return its `sources:` entry."""
        stream = Stream(name, np.asarray(t, float), tuple(columns), np.column_stack(list(columns.values())))
        write_csv_stream(self.folder / f"{name}.csv", stream)
        return {"type": "csv", "name": name, "path": f"{name}.csv"}

    def config(self, data: dict, name: str = "config.yaml") -> Path:
        path = self.folder / name
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path


@pytest.fixture(scope="session")
def simulated(tmp_path_factory) -> Path:
    """A file-based dataset (TUM data, truth, robot description, config.yaml) written once by the
    pose.scaled_vo simulator (6 s, seed 1)."""
    from fusionkit.simulate import write_dataset
    folder = tmp_path_factory.mktemp("simulated") / "ds"
    write_dataset("pose.scaled_vo", folder, ["duration=6"], seed=1)
    return folder


@pytest.fixture
def ds(simulated, tmp_path) -> Path:
    """A private copy of the simulated dataset; returns the folder (config at ds / 'config.yaml')."""
    folder = tmp_path / "ds"
    shutil.copytree(simulated, folder)
    return folder


@pytest.fixture
def workspace(tmp_path) -> Workspace:
    return Workspace(tmp_path)


@pytest.fixture
def use_plugins(monkeypatch):
    """`use_plugins(obj, ...)`: for this test, the registry holds the installed plugins plus `obj`s
    (modules or objects with `@fusionkit.hookimpl` registration hooks), as if installed.

    `fusionkit.plugins.registry` is cached and imported by name into several modules, so every
    `fusionkit.*` module that bound it is patched (and restored after the test)."""
    original = fusionkit.plugins.registry

    def install(*plugins) -> fusionkit.plugins.Registry:
        pm = fusionkit.plugins._plugin_manager()
        for i, plugin in enumerate(plugins):
            pm.register(plugin, name=f"test_plugin_{i}")
        reg = fusionkit.plugins.build_registry(pm)
        for name, module in list(sys.modules.items()):
            if name.startswith("fusionkit") and getattr(module, "registry", None) is original:
                monkeypatch.setattr(module, "registry", lambda: reg)
        return reg

    return install


def pytest_configure(config):
    """Tests call plugin internals directly too: give them the one BLAS thread fusionkit's own entry
    points use (fusionkit.threads), so a busy core does not multiply the suite's time."""
    from fusionkit.threads import one_blas_thread
    config._fusionkit_blas_limit = one_blas_thread()


def pytest_collection_modifyitems(items):
    """The longest tests first -- the executed tutorials (7-46 s each), then the rest of the slow tier: with
    `--dist worksteal` the other worker takes the short tests meanwhile, and no long test starts last and
    runs alone."""
    items.sort(key=lambda item: ("test_tutorials.py" not in item.nodeid, item.get_closest_marker("slow") is None))
