"""The framework's promise: installing the sagging-cable plugin changes nothing for rigid cables.
The quickstart (ARAS-CAM, rigid cables) runs in two processes, one with the cable_sag entry point
blocked (FUSIONKIT_BLOCK_PLUGINS, as if it were not installed); every estimate, sigma, trajectory
sample and the solver's cost history must be bit-for-bit the same."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def _run(out: Path, block: str) -> dict:
    env = {**os.environ, "FUSIONKIT_BLOCK_PLUGINS": block}
    cli = Path(sys.executable).parent / "fusionkit"
    plugins = subprocess.run([str(cli), "plugins"], env=env, capture_output=True, text=True, check=True).stdout
    subprocess.run([str(cli), "run", str(REPO / "configs/quickstart.yaml"), "--out", str(out),
                    "--set", "output.plots=false"], env=env, capture_output=True, text=True, check=True)
    report = json.loads((out / "report.json").read_text())
    return {"plugins": plugins, "parameters": report["parameters"], "evaluation": report["evaluation"],
            "cost": (report["solver"]["initial_cost"], report["solver"]["final_cost"],
                     report["solver"]["iterations"]),
            "trajectory": (out / "trajectories/cdpr.tum").read_bytes()}


@pytest.mark.slow
def test_rigid_results_identical_with_and_without_the_sag_plugin(tmp_path):
    without = _run(tmp_path / "without", "cable_sag")
    with_sag = _run(tmp_path / "with", "")
    assert "cable.sag" not in without["plugins"] and "cable.sag" in with_sag["plugins"]
    for key in ("parameters", "evaluation", "cost", "trajectory"):
        assert without[key] == with_sag[key], key
