"""The example third-party plugin, examples/fusionkit-altimeter, as a real installed package
(tests/example_packages.py: pip-installed into a private folder only the subprocesses see). As a user would:
`fusionkit plugins --json` lists it, its factor type passes the contract suite (and a broken
Jacobian would not), `fusionkit validate` reports its `check()` errors, and `fusionkit run` on
the demo config estimates the altimeter bias.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from example_packages import fusionkit_cmd, install_example, run

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "fusionkit-altimeter"
DEMO = EXAMPLE / "configs" / "demo.yaml"


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    return install_example("fusionkit-altimeter", tmp_path_factory)


def test_installed_as_a_distribution_with_entry_point(installed):
    dists = list(installed["target"].glob("fusionkit_altimeter-*.dist-info"))
    assert len(dists) == 1, list(installed["target"].iterdir())
    dist = importlib.metadata.PathDistribution(dists[0])
    eps = [ep for ep in dist.entry_points if ep.group == "fusionkit"]
    assert [(ep.name, ep.value) for ep in eps] == [("altimeter", "fusionkit_altimeter.plugin")]
    # this process (the test environment) does not see it: nothing was installed here
    assert "altimeter" not in {ep.name for ep in importlib.metadata.entry_points(group="fusionkit")}


def test_plugins_json_lists_the_example_factor_and_simulator_with_summaries(installed):
    proc = run([*fusionkit_cmd(), "plugins", "--json"], installed)
    assert proc.returncode == 0, proc.stderr
    listing = json.loads(proc.stdout)
    assert "altimeter" in listing, list(listing)
    provided = listing["altimeter"]
    assert [i["name"] for i in provided["factor_types"]] == ["altimeter.height"]
    assert [i["name"] for i in provided["simulators"]] == ["altimeter.demo"]
    assert all(i["summary"] for kind in provided.values() for i in kind)
    assert "pose.absolute" in [i["name"] for i in listing["pose"]["factor_types"]]


CONTRACT_SCRIPT = textwrap.dedent("""
    import json
    import gtsam
    import numpy as np
    from fusionkit.plugins import registry
    from fusionkit.testing import ContractFailure, FactorExample, check_factor_contract, check_factor_example
    from fusionkit_altimeter.residuals import height_residual

    reg = registry()
    cls = reg.get("factor_types", "altimeter.height")   # found through the entry point
    out = {"provider": reg.provider[("factor_types", cls.name)]}
    check_factor_contract(cls)
    out["contract"] = "passed"

    def broken(which, measured):
        def error(this, values, H):
            e = height_residual(values.atPose3(this.keys()[0]), values.atDouble(this.keys()[1]), measured, H)
            if H is not None and which == "world_z":      # world z axis instead of R's third row
                H[0] = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
            if H is not None and which == "bias_sign":
                H[1] = -H[1]
            return e
        return error

    for which in ("world_z", "bias_sign"):
        ex = cls.example(np.random.default_rng(0))
        measured = float(ex.values.atPose3(0).translation()[2] + ex.values.atDouble(1))
        bad = gtsam.CustomFactor(ex.factor.noiseModel(), ex.factor.keys(), broken(which, measured))
        try:
            check_factor_example(FactorExample(bad, ex.values), which)
            out[which] = None
        except ContractFailure as exc:
            out[which] = str(exc)
    print(json.dumps(out))
""")


def test_contract_passes_and_a_broken_jacobian_is_caught(installed):
    proc = run([sys.executable, "-c", CONTRACT_SCRIPT], installed)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["provider"] == "altimeter"
    assert out["contract"] == "passed"
    assert out["world_z"] and "Jacobian block 0" in out["world_z"], out
    assert out["bias_sign"] and "Jacobian block 1" in out["bias_sign"], out


@pytest.mark.parametrize("override, message", [
    ("factors.2.bias=nope", "factors[2].bias: robot 'drone' has no parameter 'nope'"),
    ("factors.2.stream=gnss", "factors[2].stream: stream 'gnss' (sources[0]) lacks column(s) height"),
])
def test_plugin_check_errors_are_one_line_located_in_the_demo_config(installed, override, message):
    proc = run([*fusionkit_cmd(), "validate", str(DEMO), "--set", override], installed)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert message in proc.stderr and f"{DEMO}:" in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_demo_estimates_the_bias_within_3_sigma_and_3_cm(installed):
    out = installed["root"] / "out"
    proc = run([*fusionkit_cmd(), "run", str(DEMO), "--out", str(out)], installed)
    assert proc.returncode == 0, f"{proc.stdout}\n{proc.stderr}"
    true_bias = yaml.safe_load(DEMO.read_text())["sources"][0]["params"]["bias"]

    report = json.loads((out / "report.json").read_text())
    est = report["parameters"]["drone"]["baro_bias"]
    assert abs(est["value"] - true_bias) < 3 * est["sigma"], (est, true_bias)
    assert abs(est["value"] - true_bias) < 0.03 and est["sigma"] < 0.03, est
    assert report["problem"]["factors_by_entry"]["factors[2]:altimeter.height"] == 600
    assert report["notes"] == []
    ev = report["evaluation"]
    assert abs(ev["parameters"]["drone"]["baro_bias"]["z_per_axis"][0][0]) < 3
    assert ev["trajectories"]["drone"]["ate_rmse_m"] < 0.12

    calib = yaml.safe_load((out / "calibration.yaml").read_text())
    assert calib["robots"]["drone"]["baro_bias"]["value"] == pytest.approx(est["value"])
    assert calib["robots"]["drone"]["baro_bias"]["sigma"] == pytest.approx(est["sigma"])
    assert (out / "trajectories" / "drone.tum").is_file()


@pytest.mark.slow
def test_simulated_csv_dataset_runs_and_recovers_the_bias_within_5_cm(installed):
    """`fusionkit simulate altimeter.demo` writes the altimeter as a stream CSV (t,height) with a
    runnable config: the factor works from files as well as in-process data."""
    sim, out = installed["root"] / "sim", installed["root"] / "sim_out"
    proc = run([*fusionkit_cmd(), "simulate", "altimeter.demo", "--out", str(sim), "--seed", "1",
                "--set", "duration=20", "--set", "bias=-0.8"], installed)
    assert proc.returncode == 0, proc.stderr
    assert (sim / "data" / "baro.csv").read_text().splitlines()[0] == "t,height"
    proc = run([*fusionkit_cmd(), "run", str(sim / "config.yaml"), "--out", str(out), "--no-plots"], installed)
    assert proc.returncode == 0, f"{proc.stdout}\n{proc.stderr}"
    est = json.loads((out / "report.json").read_text())["parameters"]["drone"]["baro_bias"]
    assert abs(est["value"] + 0.8) < max(3 * est["sigma"], 1e-3) and abs(est["value"] + 0.8) < 0.05, est


def test_the_plugins_own_tests_pass(installed):
    """examples/fusionkit-altimeter/tests, run against the installed package (but its end-to-end
    demo, which test_demo_estimates_the_bias_within_3_sigma_and_3_cm covers through the command line)."""
    proc = run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", "not demo",
                str(installed["root"] / "src" / "tests")], installed)
    assert proc.returncode == 0, proc.stdout[-3000:]


def _fake_distribution(folder: Path, module_source: str) -> dict:
    """A minimal installed distribution (dist-info with a `fusionkit` entry point) in `folder`."""
    (folder / "probe_plugin.py").write_text(textwrap.dedent(module_source))
    info = folder / "probe_plugin-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: probe-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[fusionkit]\nprobe = probe_plugin\n")
    return {"root": folder, "env": dict(os.environ, PYTHONPATH=str(folder))}


WARNING = ("fusionkit: warning: plugin 'probe' (entry point probe = probe_plugin of distribution probe-plugin): "
           "{reason}; its types are unavailable (configs that do not use them run)")


def test_misspelled_hook_is_named_and_the_plugin_left_out(tmp_path):
    """A @hookimpl whose name is no hook (here `register_factor_type`) is named with its distribution
    and entry point on every command, and the plugin is left out; the rest works."""
    fake = _fake_distribution(tmp_path, """
        from fusionkit.api import hookimpl

        @hookimpl
        def register_factor_type():
            return []
    """)
    proc = run([*fusionkit_cmd(), "plugins", "--json"], fake)
    assert proc.returncode == 0, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert line.startswith(WARNING.split("{reason}")[0]) and "unknown hook 'register_factor_type'" in line
    assert "probe" not in json.loads(proc.stdout) and "pose" in json.loads(proc.stdout)


@pytest.mark.slow
def test_plugin_that_fails_to_import_does_not_stop_configs_that_do_not_use_it(tmp_path):
    fake = _fake_distribution(tmp_path, """
        import a_module_that_is_not_installed
    """)
    config = REPO / "configs" / "scaled_vo_mocap.yaml"
    proc = run([*fusionkit_cmd(), "validate", str(config), "--set", "sources.0.params.duration=4"], fake)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [WARNING.format(
        reason="ModuleNotFoundError: No module named 'a_module_that_is_not_installed'")]
    proc = run([*fusionkit_cmd(), "validate", str(config), "--set", "factors.0.type=probe.altimeter"], fake)
    assert proc.returncode == 2
    error = proc.stderr.splitlines()[-1]
    assert "factors[0].type: unknown factor type 'probe.altimeter'; installed: " in error
    assert error.endswith("1 plugin(s) failed to load: plugin 'probe' (entry point probe = probe_plugin of "
                          "distribution probe-plugin): ModuleNotFoundError: No module named "
                          "'a_module_that_is_not_installed' (from --set factors.0.type=probe.altimeter)")


def test_only_marked_functions_are_hooks(tmp_path):
    """A function with a hook's name but without @hookimpl is not called."""
    fake = _fake_distribution(tmp_path, """
        def register_factor_types():
            raise RuntimeError("called although not marked @hookimpl")
    """)
    proc = run([*fusionkit_cmd(), "plugins", "--json"], fake)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["probe"] == {}


@pytest.mark.parametrize("declared, accepted", [("1.99", False), ("2.0", False), ("one", False), ("1.0", True)])
def test_a_plugin_written_for_another_api_version_is_refused_in_one_line(tmp_path, declared, accepted):
    """FUSIONKIT_API in the entry-point module: a future minor version or another major one is refused with one line
    naming the plugin and both versions, and its types are unavailable; an older minor version of the same major
    loads."""
    from fusionkit.api import API_VERSION
    fake = _fake_distribution(tmp_path, f"""
        from fusionkit.api import hookimpl, Simulator

        FUSIONKIT_API = "{declared}"

        class Probe(Simulator):
            name = "probe.sim"
            summary = "nothing"

        @hookimpl
        def register_simulators():
            return [Probe]
    """)
    proc = run([*fusionkit_cmd(), "plugins", "--json"], fake)
    assert proc.returncode == 0, proc.stderr
    listed = json.loads(proc.stdout)
    if accepted:
        assert proc.stderr == "" and "probe.sim" in json.dumps(listed["probe"])
        return
    (line,) = proc.stderr.splitlines()
    assert line.startswith(WARNING.split("{reason}")[0]) and "probe" not in listed
    if declared == "one":
        assert f"FUSIONKIT_API = 'one' is not a version 'major.minor' (this fusionkit provides {API_VERSION})" in line
    else:
        assert f"written for fusionkit API {declared}; this fusionkit provides API {API_VERSION}" in line


def test_every_plugin_family_declares_the_api_it_is_written_for():
    """The built-in families declare the current API (they are written exactly as a third-party package)."""
    import importlib
    from fusionkit.api import API_VERSION
    from fusionkit.plugins import _entry_points, api_mismatch
    own = [ep for dist, ep in _entry_points() if dist == "fusionkit"]
    assert len(own) == 10  # pose, imu, motion, cable_rigid, cable_sag, uwb, serial_arm, arash, wheels, epuck
    for ep in own:
        declared = importlib.import_module(ep.value).FUSIONKIT_API
        assert declared == API_VERSION and api_mismatch(declared) is None
