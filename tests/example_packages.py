"""The example third-party packages (examples/fusionkit-*) installed as real distributions for a test module.

Each is pip-installed (dist-info with its entry point) into a private folder that only the subprocesses see
through PYTHONPATH: the test environment is not modified. Tests that need one are skipped only when pip is
unavailable."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _builds_without_isolation() -> bool:
    """Can this environment build the example without fetching build requirements?

    setuptools' PEP 517 backend makes wheels by itself from 70.1; older ones need the `wheel`
    distribution (its metadata registers the bdist_wheel command)."""
    def version(dist: str) -> tuple[int, ...] | None:
        try:
            return tuple(int(p) for p in importlib.metadata.version(dist).split(".")[:2] if p.isdigit())
        except importlib.metadata.PackageNotFoundError:
            return None
    setuptools = version("setuptools")
    return setuptools is not None and (setuptools >= (70, 1) or version("wheel") is not None)


def fusionkit_cmd() -> list[str]:
    script = Path(sys.executable).parent / "fusionkit"
    return [str(script)] if script.exists() else [sys.executable, "-m", "fusionkit.cli.main"]


def install_example(name: str, tmp_path_factory) -> dict:
    """pip-install a copy of examples/`name` (so no build/ or egg-info/ lands in the repository) into a target
    folder; return {"target", "env" (that makes it importable), "root" (a scratch folder, the copy in src/)}."""
    if importlib.util.find_spec("pip") is None:
        pytest.skip("pip is not available to install the example package")
    root = tmp_path_factory.mktemp(name)
    src, target = root / "src", root / "site"
    shutil.copytree(EXAMPLES / name, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "out"))
    cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-compile", "--target",
           str(target), str(src)]
    if _builds_without_isolation():
        cmd.insert(4, "--no-build-isolation")
    # otherwise pip builds in an isolated environment with setuptools from its index: still
    # nothing is installed into this environment.
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"pip install failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(target), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return {"target": target, "env": env, "root": root}


def run(args: list[str], installed: dict, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(args, env=installed["env"], cwd=installed["root"], capture_output=True, text=True,
                          timeout=120, **kw)
