"""A variable type the core does not know, added by a third-party package and used in a run: examples/
fusionkit-camera registers `cal3_s2` (pinhole intrinsics [fx, fy, skew, u0, v0], GTSAM's Cal3_S2) and the
vectorized `camera.pixel` factor on it, touching no core file. Installed as a real distribution
(tests/example_packages.py): listed by `fusionkit plugins`, its factor passes the contract suite (a wrong
intrinsics Jacobian would not), the type's array form, retraction and time interpolation agree with GTSAM's,
a run calibrates the intrinsics to within 3 sigma of the simulated truth and prints, reports and writes them by
the type's own component names, and a calibration file of the type is read back with its names checked."""

from __future__ import annotations

import json
import sys
import textwrap

import numpy as np
import pytest
import yaml
from example_packages import EXAMPLES, fusionkit_cmd, install_example, run

DEMO = EXAMPLES / "fusionkit-camera" / "configs" / "demo.yaml"
TRUE_K = [525.0, 518.0, 0.0, 316.0, 243.0]  # camera.demo's default intrinsics
AXES = ["fx", "fy", "skew", "u0", "v0"]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    return install_example("fusionkit-camera", tmp_path_factory)


def test_plugins_lists_the_variable_type_with_its_components(installed):
    proc = run([*fusionkit_cmd(), "plugins", "--json"], installed)
    assert proc.returncode == 0, proc.stderr
    provided = json.loads(proc.stdout)["camera"]
    (vartype,) = provided["variable_types"]
    assert (vartype["name"], vartype["dim"], vartype["components"], vartype["axes"]) == ("cal3_s2", 5, AXES, AXES)
    assert [i["name"] for i in provided["factor_types"]] == ["camera.pixel"]
    assert "pose3" in [i["name"] for i in json.loads(proc.stdout)["fusionkit.graph.variables"]["variable_types"]]
    proc = run([*fusionkit_cmd(), "plugins", "cal3_s2"], installed)
    assert proc.returncode == 0 and proc.stdout.splitlines()[0].startswith("variable type cal3_s2 (camera): ")


TYPE_SCRIPT = textwrap.dedent("""
    import json
    import gtsam
    import numpy as np
    from fusionkit.plugins import registry, variable_type
    from fusionkit.graph.vectorized import ValueReader
    from fusionkit.time_offset.interpolation import interpolate, operations
    from fusionkit.testing import ContractFailure, FactorExample, check_factor_contract, check_factor_example
    from fusionkit.api import VectorizedResidual, vectorized_factor
    from fusionkit_camera.residuals import PIXEL, pixel_residual

    out = {}
    vt = variable_type("cal3_s2")                      # found through the entry point, as any config finds it
    k0, k1 = gtsam.Cal3_S2(500, 480, 0.5, 320, 240), gtsam.Cal3_S2(520, 470, -0.5, 330, 250)
    d = np.array([1.0, -2.0, 0.1, 3.0, -4.0])
    values = gtsam.Values()
    values.insert(7, k0)
    out["array_vs_gtsam"] = float(np.max(np.abs(ValueReader(values).read(vt, np.array([7, 7])) - k0.vector())))
    out["retract_vs_gtsam"] = float(np.max(np.abs(vt.retract_array(vt.to_array(k0)[None], d[None])[0]
                                                  - k0.retract(d).vector())))
    out["local"] = vt.local(k0, k0.retract(d)).tolist()
    mid = interpolate(vt, np.array([0.0, 1.0]), [k0, k1], 0.25)    # two states: the chord, on the vector form
    out["interpolated_type"] = type(mid).__name__
    out["interpolated_error"] = float(np.max(np.abs(mid.vector() - (0.75 * k0.vector() + 0.25 * k1.vector()))))
    out["operations"] = type(operations(vt)).__name__

    cls = registry().get("factor_types", "camera.pixel")
    check_factor_contract(cls)
    out["contract"] = "passed"

    def wrong_principal_point(x, data, jacobians):            # d u / d u0 with the wrong sign
        if not jacobians:
            return pixel_residual(x, data, False)
        r, (d_pose, d_k) = pixel_residual(x, data, True)
        d_k = d_k.copy()
        d_k[:, 0, 3] = -1.0
        return r, [d_pose, d_k]
    ex = cls.example(np.random.default_rng(0))
    broken = VectorizedResidual("broken", PIXEL.variables, 2, wrong_principal_point)
    pose, k = ex.values.atPose3(0), ex.values.atCal3_S2(1)
    point = pose.transformFrom(np.array([0.2, -0.1, 3.0]))
    pixel = pixel_residual([pose.matrix()[None], k.vector()[None]], {"point": point[None], "pixel": np.zeros((1, 2))},
                           False)[0]
    bad = vectorized_factor(broken, ex.factor.noiseModel(), [0, 1], {"point": point[None], "pixel": pixel[None]})
    try:
        check_factor_example(FactorExample(bad, ex.values), "wrong u0 Jacobian")
        out["broken"] = None
    except ContractFailure as exc:
        out["broken"] = str(exc)
    print(json.dumps(out))
""")


def test_type_operations_agree_with_gtsam_and_the_contract_catches_a_wrong_jacobian(installed):
    proc = run([sys.executable, "-c", TYPE_SCRIPT], installed)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["array_vs_gtsam"] == 0.0 and out["retract_vs_gtsam"] < 1e-12
    np.testing.assert_allclose(out["local"], [1.0, -2.0, 0.1, 3.0, -4.0], atol=1e-12)
    assert out["operations"] == "_Linear" and out["interpolated_type"] == "Cal3_S2"
    assert out["interpolated_error"] < 1e-9
    assert out["contract"] == "passed"
    assert out["broken"] and "Jacobian block 1" in out["broken"], out


@pytest.mark.slow
def test_a_run_calibrates_the_intrinsics_within_3_sigma_and_reports_them_by_name(installed):
    out = installed["root"] / "out"
    proc = run([*fusionkit_cmd(), "run", str(DEMO), "--out", str(out), "--no-plots"], installed)
    assert proc.returncode == 0, f"{proc.stdout}\n{proc.stderr}"
    assert "rig/K = fx 52" in proc.stdout and " px " in proc.stdout, proc.stdout
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "accepted"
    est = report["parameters"]["rig"]["K"]
    assert est["type"] == "cal3_s2" and est["components"] == AXES and est["sigma_components"] == AXES
    z = (np.asarray(est["value"]) - TRUE_K) / np.asarray(est["sigma"])
    assert np.all(np.abs(z) < 3), z
    assert np.all(np.asarray(est["sigma"]) < 0.5), est            # px: the pixels, not the 100 px prior, decide
    assert report["identifiability"]["parameters"] == [f"rig/K.{a}" for a in AXES]
    assert report["identifiability"]["units"] == ["px"] * 5
    assert report["evaluation"]["trajectories"]["rig"]["ate_rmse_m"] < 0.003

    calibration = yaml.safe_load((out / "calibration.yaml").read_text())["robots"]["rig"]["K"]
    assert calibration["components"] == AXES and calibration["value"] == pytest.approx(est["value"])

    # the calibration read back as a description override; names in another order are refused at their line
    config = yaml.safe_load(DEMO.read_text())
    config["robots"]["rig"]["description"] = str(DEMO.parent.parent / "robots" / "rig.yaml")
    config["robots"]["rig"]["overrides"] = str(out / "calibration.yaml")
    (installed["root"] / "again.yaml").write_text(yaml.safe_dump(config))
    proc = run([*fusionkit_cmd(), "validate", "again.yaml"], installed)
    assert proc.returncode == 0, proc.stderr
    text = (out / "calibration.yaml").read_text().replace("components: [fx, fy, skew, u0, v0]\n      sigma:",
                                                          "components: [fy, fx, skew, u0, v0]\n      sigma:")
    (out / "calibration.yaml").write_text(text)
    proc = run([*fusionkit_cmd(), "validate", "again.yaml"], installed)
    assert proc.returncode == 2
    assert "rig.K.components: got [fy, fx, skew, u0, v0]; expected [fx, fy, skew, u0, v0]" in proc.stderr, proc.stderr


@pytest.mark.slow
def test_the_plugins_own_tests_pass(installed):
    """examples/fusionkit-camera/tests, run against the installed package."""
    proc = run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(installed["root"] / "src" / "tests")],
               installed)
    assert proc.returncode == 0, proc.stdout[-3000:]
