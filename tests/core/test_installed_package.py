"""The installed package is the library alone: fusionkit built NON-editable from a copy of the
repository's sources holds every module and robot description and nothing else, and installed into a
fresh virtual environment it runs the quickstart and a simulator from a folder outside the
repository (robot descriptions come from the package, nothing is read from the repository)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
BUILD_INPUTS = ("pyproject.toml", "setup.py", "README.md", "fusionkit", "plugins", "robots")


def _run(cmd: list, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "FUSIONKIT_BLOCK_PLUGINS")}
    return subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def _repository_modules_and_descriptions() -> set[str]:
    """Every module under fusionkit/ and plugins/ and every robots/<family>/*.yaml (and a URDF shipped beside
    them), by the path a wheel stores it under (plugins/ is the package fusionkit_plugins, robots/ the data
    package fusionkit_robots)."""
    names = {str(p.relative_to(REPO)) for p in (REPO / "fusionkit").rglob("*.py")}
    names.update("fusionkit_plugins/" + str(p.relative_to(REPO / "plugins")) for p in (REPO / "plugins").rglob("*.py"))
    for p in [REPO / "robots" / "__init__.py", *(REPO / "robots").glob("*/*.yaml"), *(REPO / "robots").glob("*/*.urdf")]:
        names.add("fusionkit_robots/" + str(p.relative_to(REPO / "robots")))
    return names


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel pip builds (no isolation, no network) from a copy of the build inputs."""
    root = tmp_path_factory.mktemp("wheel")
    src = root / "src"
    src.mkdir()
    for name in BUILD_INPUTS:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy(REPO / name, src / name)
    proc = _run([sys.executable, "-m", "pip", "wheel", "-v", "--no-deps", "--no-build-isolation", "--no-index",
                 "--wheel-dir", root / "dist", src], root)
    if proc.returncode != 0 and "No module named pip" in proc.stderr:
        pytest.skip("pip is not available in the test environment")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (root / "build.log").write_text(proc.stdout + proc.stderr)  # -v: with setuptools' own output
    return next((root / "dist").glob("fusionkit-*.whl"))


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """bin/ of a fresh virtual environment with the wheel installed. Its dependencies (gtsam,
    numpy, ...) are the test environment's, reached through a .pth file that lists its
    site-packages folders: their own .pth files (fusionkit's editable hook) are not run, and pip
    ignores the fusionkit installed there (never uninstalls it)."""
    env = tmp_path_factory.mktemp("venv") / "env"
    try:
        venv.create(env, with_pip=False)
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"cannot create a virtual environment: {exc}")
    python = env / "bin" / "python"
    purelib = _run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"], env).stdout.strip()
    dependencies = [p for p in sys.path if p.endswith(("site-packages", "dist-packages")) and Path(p).is_dir()]
    (Path(purelib) / "test_dependencies.pth").write_text("\n".join(dependencies) + "\n")
    proc = _run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index",
                 "--ignore-installed", wheel], env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return env / "bin"


def test_wheel_holds_exactly_the_modules_and_robot_descriptions(wheel):
    """No module or description forgotten (package discovery, package data), and nothing else: no
    research code, tests, configs or data."""
    with zipfile.ZipFile(wheel) as z:
        stored = {n for n in z.namelist() if ".dist-info/" not in n}
    assert stored == _repository_modules_and_descriptions()
    assert "fusionkit_robots/cable_rigid/arascam.yaml" in stored


def test_the_build_prints_no_setuptools_warning(wheel):
    """Neither `[tool.setuptools]`'s "still beta" warning nor one "Package would be ignored" per family folder
    of robots/ (a namespace package Python can import, package data here): the first `make` printed some 350
    lines of them."""
    log = (wheel.parent.parent / "build.log").read_text()
    assert "Building wheel for fusionkit" in log  # the backend's output is there
    warned = [line for line in log.splitlines() if re.search(r"\w*Warning\b|is absent from the `packages`", line)
              and "Location 'file:" not in line]
    assert warned == []


def test_installed_package_is_imported_from_the_venv_not_the_repository(installed, tmp_path):
    proc = _run([installed / "python", "-c", "import fusionkit, fusionkit_plugins; "
                 "print(fusionkit.__file__); print(fusionkit_plugins.__file__)"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    files = [Path(line) for line in proc.stdout.split()]
    assert len(files) == 2 and all(f.is_relative_to(installed.parent) for f in files), files


@pytest.mark.slow
def test_quickstart_from_another_folder_self_calibrates_as_in_the_repository(installed, tmp_path):
    """A copy of configs/quickstart.yaml (`description: arascam`, by name) in a folder of its own:
    the same bounds as tests/plugins/cable_rigid/test_configs.py (measured: scale error 0.0009,
    pulleys 3.5 cm, offsets 3.0 cm, ATE 4.4 mm)."""
    shutil.copy(REPO / "configs" / "quickstart.yaml", tmp_path / "quickstart.yaml")
    proc = _run([installed / "fusionkit", "run", "quickstart.yaml", "--out", "out", "--no-plots", "-q"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    ev = json.loads((tmp_path / "out" / "report.json").read_text())["evaluation"]
    assert ev["parameters"]["cdpr"]["vo_scale"]["abs_error"][0] < 0.005
    assert ev["parameters"]["cdpr"]["pulley"]["mean_abs_error"] < 0.06
    assert ev["parameters"]["cdpr"]["offset"]["mean_abs_error"] < 0.05
    assert ev["trajectories"]["cdpr"]["ate_rmse_m"] < 0.01


def test_simulate_from_another_folder_writes_the_shipped_robot_and_its_data(installed, tmp_path):
    """`fusionkit simulate cable.cdpr` reads the arascam description from the installed package: the
    written description has its nominal pulleys, the data 30 Hz x 2 s of four cable lengths."""
    proc = _run([installed / "fusionkit", "simulate", "cable.cdpr", "--out", "sim", "--set", "duration=2"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    shipped = yaml.safe_load((REPO / "robots" / "cable_rigid" / "arascam.yaml").read_text())
    written = yaml.safe_load((tmp_path / "sim" / "robots" / "cdpr.yaml").read_text())
    assert written["parameters"]["pulley"]["values"] == shipped["parameters"]["pulley"]["values"]
    lengths = (tmp_path / "sim" / "data" / "lengths.csv").read_text().split()
    assert lengths[0] == "t,l0,l1,l2,l3" and len(lengths) == 1 + 60
