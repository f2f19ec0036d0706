"""The variable machinery serves every family: conversions, priors and betweens on gtsam.Values,
tangent-space errors; keys carry readable names; planar robots and time-varying parameters work
end to end."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import fusionkit
import fusionkit.api
from fusionkit.api import CheckScope, FactorType, Spec
from fusionkit.config.yamlio import Document
from fusionkit.graph.builder import STATIC_TIME, BuildContext
from fusionkit.graph.keys import INDEX_BITS, STATE, STATIC, TIME_VARYING, KeyRegistry
from fusionkit.graph.noise import gaussian
from fusionkit.graph.variables import POSE2, POSE3, SCALAR
from fusionkit.plugins import variable_type, variable_type_names
from fusionkit.pipeline import read_sources
from fusionkit.descriptions.description import description_from_document
from fusionkit.testing import FactorExample, check_factor_contract

# name -> (YAML value, dim)
FAMILIES = {
    "pose3": ([1.0, -2.0, 0.5, 0.0, 0.0, float(np.sin(0.3)), float(np.cos(0.3))], 6),
    "pose2": ([1.0, -2.0, 0.7], 3),
    "point3": ([0.1, 0.2, 3.0], 3),
    "point2": ([4.0, -1.0], 2),
    "rot3": ([0.1, -0.2, 0.3], 3),
    "scalar": (2.5, 1),
    "vector7": ([0.1, -0.4, 0.3, 1.2, -0.5, 0.2, 0.0], 7),   # joint angles of a 7-dof arm
    "vector12": (list(np.linspace(-1.0, 1.0, 12)), 12),     # a kinematic-parameter vector
    "velocity3": ([0.5, 0.0, -0.1], 3),
    "imu_bias": ([0.01, -0.02, 0.03, 0.001, 0.002, -0.003], 6),
}


def _as_array(x) -> np.ndarray:
    return np.atleast_1d(np.asarray(x, float))


@pytest.mark.parametrize("name", FAMILIES)
def test_family_round_trips_and_prior_and_between_measure_the_same_tangent_delta(name):
    raw, dim = FAMILIES[name]
    vt = variable_type(name)
    assert (vt.name, vt.dim) == (name, dim)
    value = vt.from_list(raw)
    np.testing.assert_allclose(_as_array(vt.to_list(value)), _as_array(raw), atol=1e-12)
    np.testing.assert_allclose(_as_array(vt.to_list(vt.from_list(vt.to_list(value)))), _as_array(raw), atol=1e-12)

    # b = a (+) delta on the manifold; everything must measure the same tangent vector
    delta = np.linspace(0.02, 0.09, dim)
    a = gtsam.Values()
    a.insert(1, value)
    step = gtsam.VectorValues()
    step.insert(1, delta)
    moved = vt.read(a.retract(step), 1)
    assert a.zeroVectors().at(1).shape == (dim,)
    np.testing.assert_allclose(vt.local(value, moved), delta, atol=1e-12)
    np.testing.assert_allclose(vt.local(value, value), np.zeros(dim), atol=1e-12)

    values = gtsam.Values()
    values.insert(1, value)
    values.insert(2, moved)
    sigmas = np.linspace(0.1, 0.5, dim)
    prior = vt.prior(2, value, gaussian(sigmas))
    between = vt.between(1, 2, vt.zero(), gaussian(sigmas))
    np.testing.assert_allclose(prior.unwhitenedError(values), delta, atol=1e-12)
    np.testing.assert_allclose(between.unwhitenedError(values), delta, atol=1e-12)
    np.testing.assert_allclose(between.whitenedError(values), delta / sigmas, atol=1e-12)
    assert between.error(values) == pytest.approx(0.5 * np.sum((delta / sigmas) ** 2), rel=1e-12)
    assert prior.error(vt_values(vt, 2, value)) == pytest.approx(0.0, abs=1e-20)
    assert between.error(vt_values(vt, 1, value, 2, value)) == pytest.approx(0.0, abs=1e-20)


def vt_values(vt, *pairs) -> gtsam.Values:
    v = gtsam.Values()
    for key, value in zip(pairs[::2], pairs[1::2]):
        v.insert(key, value)
    return v


def test_local_matches_hand_computations():
    """Vector spaces subtract; Pose3/Rot3 rotation parts are the rotation vector of Ra^T Rb
    (GTSAM tangent order [rotation, translation]); Pose2 is [x, y, theta] in a's frame."""
    for name in ("point3", "point2", "scalar", "vector7", "velocity3", "imu_bias"):
        vt = variable_type(name)
        raw, dim = FAMILIES[name]
        a = vt.from_list(raw)
        b = vt.from_list(list(_as_array(raw) + np.arange(1, dim + 1) * 0.1) if dim > 1 else float(raw) + 0.1)
        np.testing.assert_allclose(vt.local(a, b), np.arange(1, dim + 1) * 0.1, atol=1e-12)
    ra, rb = gtsam.Rot3.RzRyRx(0.1, 0.2, 0.3), gtsam.Rot3.RzRyRx(-0.2, 0.4, 1.0)
    rotvec = Rotation.from_matrix(ra.matrix().T @ rb.matrix()).as_rotvec()
    np.testing.assert_allclose(variable_type("rot3").local(ra, rb), rotvec, atol=1e-12)
    pa, pb = gtsam.Pose3(ra, np.array([1.0, 2.0, 3.0])), gtsam.Pose3(rb, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(POSE3.local(pa, pb)[:3], rotvec, atol=1e-12)
    # a pure translation in a's frame: Log has no rotation and the translation R_a^T (t_b - t_a)
    pc = gtsam.Pose3(ra, np.array([1.5, 1.0, 3.2]))
    np.testing.assert_allclose(POSE3.local(pa, pc), np.r_[np.zeros(3), ra.matrix().T @ [0.5, -1.0, 0.2]], atol=1e-12)
    c, s = np.cos(0.7), np.sin(0.7)
    np.testing.assert_allclose(POSE2.local(gtsam.Pose2(1.0, 2.0, 0.7), gtsam.Pose2(1.0 + c, 2.0 + s, 0.7)),
                               [1.0, 0.0, 0.0], atol=1e-12)


def test_pose3_value_formats_agree_and_malformed_values_are_refused():
    expected = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.1, 0.2, 0.3), np.array([1.0, 2.0, 3.0]))
    for raw in ({"translation": [1, 2, 3], "rotation_rpy": [0.1, 0.2, 0.3]},
                {"translation": [1, 2, 3], "quaternion_xyzw": POSE3.to_list(expected)[3:]},
                expected.matrix(), POSE3.to_list(expected)):
        assert POSE3.from_list(raw).equals(expected, 1e-12)
    q = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_quat()  # extrinsic x-y-z = Rz Ry Rx
    assert variable_type("rot3").from_list(list(q)).equals(gtsam.Rot3.RzRyRx(0.1, 0.2, 0.3), 1e-12)
    for name, bad in (("pose3", [1, 2, 3]), ("pose2", [1, 2]), ("point3", [1, 2]), ("scalar", True),
                      ("scalar", "1.0"), ("imu_bias", [0] * 5), ("vector7", [0] * 6), ("rot3", [0, 0])):
        with pytest.raises(ValueError):
            variable_type(name).from_list(bad)
    with pytest.raises(ValueError, match="installed: .*vectorN"):
        variable_type("pose4")
    assert variable_type("vector5").dim == 5 and "vectorN" in variable_type_names()


def test_factor_checks_ask_for_a_family_by_its_name(workspace):
    """`CheckScope.require_parameter(..., vartype)` compares family names: every accepted type
    name (velocity3 included) must be the name its parameters report."""
    params = {name: {"type": name, "value": raw} for name, (raw, _) in FAMILIES.items()}
    desc = description_from_document(Document({"name": "rig", "parameters": params}, Path("<rig>")))
    scope = CheckScope({"rig": desc}, {})
    for name in FAMILIES:
        spec = Spec({"type": "test", "robot": "rig", "parameter": name}, desc.doc, ("factors", 0))
        scope.require_parameter(spec, "robot", "parameter", name)
        assert desc.parameters[name].vartype.name == name
    spec = Spec({"type": "test", "robot": "rig", "parameter": "velocity3"}, desc.doc, ("factors", 0))
    with pytest.raises(fusionkit.api.ConfigError, match="parameter 'velocity3' is a velocity3; expected a vector3"):
        scope.require_parameter(spec, "robot", "parameter", "vector3")


# --- keys ------------------------------------------------------------------------------------------

def test_key_registry_names_and_decodes():
    keys = KeyRegistry()
    pose = keys.family("cam", "pose", POSE3, STATE)
    scale = keys.family("cam", "vo_scale", SCALAR, STATIC, indexed=False)
    pulley = keys.family("cam", "pulley", variable_type("point3"), STATIC)
    bias = keys.family("cam", "bias", SCALAR, TIME_VARYING)
    other = keys.family("rig", "pose", POSE3, STATE)
    assert keys.name_of(pose.key(12)) == "cam/pose[12]"
    assert keys.name_of(scale.key(0)) == "cam/vo_scale"
    assert keys.name_of(pulley.key(2)) == "cam/pulley[2]"
    assert keys.name_of(bias.key(7)) == "cam/bias[7]"
    assert keys.name_of(other.key(12)) == "rig/pose[12]" and other.key(12) != pose.key(12)
    big = (1 << INDEX_BITS) - 1
    for fam, index in ((pose, 0), (pose, 12), (pose, big), (scale, 0), (pulley, 2), (bias, 7), (other, 3)):
        assert keys.decode(fam.key(index)) == (fam, index)
    assert keys.family("cam", "pose", POSE3, STATE) is pose  # fetching again is fine
    assert keys.get("cam", "vo_scale") is scale and keys.get("cam", "nothing") is None
    assert [f.name for f in keys.families()] == ["pose", "vo_scale", "pulley", "bias", "pose"]
    with pytest.raises(ValueError, match="cam/pose declared as state pose3 and again as state pose2"):
        keys.family("cam", "pose", POSE2, STATE)
    with pytest.raises(ValueError, match="cam/vo_scale declared as static scalar and again as time_varying"):
        keys.family("cam", "vo_scale", SCALAR, TIME_VARYING)
    with pytest.raises(KeyError):
        keys.decode(99 << INDEX_BITS)
    assert keys.name_of(99 << INDEX_BITS).startswith("<unknown key")


CAM = {"name": "cam", "sensors": {},
       "parameters": {"vo_scale": {"type": "scalar", "value": 1.0, "sigma": 10.0},
                      "pulley": {"type": "point3", "values": [[0, 0, 3], [4, 0, 3], [4, 4, 3]],
                                 "sigma": [[0.1, 0.1, 0.1], [0.2, 0.2, 0.2], [0.5, 0.5, 0.3]]},
                      "joint_offsets": {"type": "vector7", "value": [0.0] * 7},
                      "drift": {"type": "scalar", "value": 0.3, "sigma": 0.2, "time_varying": True}}}


@pytest.fixture
def context(workspace) -> BuildContext:
    t = np.arange(5) * 0.1
    sources = [workspace.poses("clock", t, [gtsam.Pose3()] * 5)]
    config = fusionkit.load_config(workspace.config({
        "robots": {"cam": {"description": CAM, "states": {"stream": "clock"}}}, "sources": sources,
        "factors": [{"type": "pose.origin", "robot": "cam", "sigma": {"rotation": 0.1, "translation": 0.1}}]}))
    streams, _ = read_sources(config)
    return BuildContext(config, streams)


def test_description_parameters_become_named_variables_with_priors(context):
    ctx = context
    scale = ctx.parameter("cam", "vo_scale")
    assert ctx.parameter("cam", "vo_scale") == scale  # one variable, declared once
    pulley2 = ctx.parameter("cam", "pulley", 2)
    joints = ctx.parameter("cam", "joint_offsets")
    drift3 = ctx.parameter("cam", "drift", k=3)
    drift0 = ctx.parameter("cam", "drift", k=0)
    assert [ctx.keys.name_of(k) for k in (scale, pulley2, joints, drift3, drift0)] == \
        ["cam/vo_scale", "cam/pulley[2]", "cam/joint_offsets", "cam/drift[3]", "cam/drift[0]"]
    np.testing.assert_allclose(ctx.initial.atPoint3(pulley2), [4, 4, 3])
    np.testing.assert_allclose(ctx.initial.atVector(joints), np.zeros(7))
    assert ctx.initial.atDouble(drift3) == 0.3
    assert ctx.key_time[scale] == STATIC_TIME and ctx.key_time[drift3] == pytest.approx(0.3)
    priors = {r.label: r for r in ctx.records}
    # priors: one per element with its own sigma; none without sigma; time-varying: first state only
    assert set(priors) == {"prior:cam/vo_scale", "prior:cam/pulley", "prior:cam/drift"}
    np.testing.assert_allclose(np.asarray(priors["prior:cam/pulley"].factor.noiseModel().sigmas()), [0.5, 0.5, 0.3])
    assert list(priors["prior:cam/drift"].factor.keys()) == [drift0]
    with pytest.raises(ValueError, match="time-varying: pass the state index k"):
        ctx.parameter("cam", "drift")


def test_redeclaring_a_family_with_another_type_errors(context):
    ctx = context
    ctx.state_variable("cam", "velocity", variable_type("velocity3"), 0)
    with pytest.raises(ValueError, match="cam/velocity declared as state velocity3 and again as state imu_bias"):
        ctx.state_variable("cam", "velocity", variable_type("imu_bias"), 1)
    with pytest.raises(ValueError, match="cam/pose declared as state pose3"):
        ctx.state_variable("cam", "pose", POSE2, 0)
    bias = ctx.state_variable("cam", "bias", variable_type("imu_bias"), 2)
    assert ctx.keys.name_of(bias) == "cam/bias[2]"
    assert ctx.initial.atConstantBias(bias).vector().tolist() == [0.0] * 6


def test_declared_values_reach_the_values_once_with_the_last_value_set(context):
    ctx = context
    keys = ctx.state_keys("cam", [0, 1, 1, 3])
    assert keys == [ctx.state_key("cam", k) for k in (0, 1, 1, 3)]
    assert [ctx.keys.name_of(k) for k in keys] == ["cam/pose[0]", "cam/pose[1]", "cam/pose[1]", "cam/pose[3]"]
    assert [ctx.key_time[k] for k in keys] == [ctx.state_time("cam", k) for k in (0, 1, 1, 3)]
    assert ctx.has_variable(keys[3]) and not ctx.has_variable(ctx.states["cam"].key(2))
    moved = gtsam.Pose3(gtsam.Rot3.Yaw(0.5), np.array([1.0, 2.0, 3.0]))
    ctx.set_initial(keys[1], moved)
    assert ctx.initial_value(keys[1]).equals(moved, 0.0) and ctx.initial_value(keys[0]).equals(gtsam.Pose3(), 0.0)
    ctx.set_initial(keys[3], moved.inverse())
    values = ctx.initial  # every declared variable, with the last value each was given
    assert values.size() == 3
    assert values.atPose3(keys[3]).equals(moved.inverse(), 0.0) and values.atPose3(keys[1]).equals(moved, 0.0)
    ctx.set_initial(keys[0], moved)  # already in the Values: updated there
    assert ctx.initial.atPose3(keys[0]).equals(moved, 0.0)
    with pytest.raises(RuntimeError):  # gtsam refuses another type for a declared pose, as before
        ctx.set_initial(ctx.state_key("cam", 4), gtsam.Pose2())
    with pytest.raises(KeyError, match=r"cam/pose\[2\] is not a variable of the graph"):
        ctx.set_initial(ctx.states["cam"].key(2), moved)


def test_a_declared_array_is_copied_so_later_changes_to_it_do_not_leak_in(context):
    ctx = context
    velocity = np.array([1.0, 2.0, 3.0])
    first = ctx.state_variable("cam", "velocity", variable_type("velocity3"), 0, velocity)
    second = ctx.state_variable("cam", "velocity", variable_type("velocity3"), 1)
    velocity[:] = -1.0
    ctx.set_initial(second, velocity)
    velocity[:] = 7.0
    assert ctx.initial.atVector(first).tolist() == [1.0, 2.0, 3.0]
    assert ctx.initial.atVector(second).tolist() == [-1.0, -1.0, -1.0]


def test_keys_group_by_family_in_ascending_order():
    keys = KeyRegistry()
    pose = keys.family("cam", "pose", POSE3, STATE)
    scale = keys.family("cam", "vo_scale", SCALAR, STATIC, indexed=False)
    assert pose.keys([3, 0, 7]) == [pose.key(3), pose.key(0), pose.key(7)]
    grouped = keys.group([scale.key(0), pose.key(7), pose.key(0), pose.key(3)])
    assert grouped == [(pose, [pose.key(0), pose.key(3), pose.key(7)]), (scale, [scale.key(0)])]
    assert keys.group([]) == []
    with pytest.raises(KeyError):
        keys.group([99 << INDEX_BITS])


# --- planar robots ---------------------------------------------------------------------------------

def planar_dataset(rng, n=300, rate=10.0, odo_sigma=(0.01, 0.01, 0.003), abs_sigma=(0.02, 0.02, 0.01)):
    t = np.arange(n) / rate
    w = 2 * np.pi / 20.0
    x, y = 3 * np.sin(w * t), 2 * np.sin(2 * w * t)
    theta = np.unwrap(np.arctan2(4 * w * np.cos(2 * w * t), 3 * w * np.cos(w * t)))
    truth = [gtsam.Pose2(*p) for p in zip(x, y, theta)]
    odo = [gtsam.Pose2()]
    for a, b in zip(truth[:-1], truth[1:]):
        odo.append(odo[-1].compose(a.between(b).compose(gtsam.Pose2.Expmap(rng.normal(0, odo_sigma)))))
    rows = np.arange(0, n, 20)
    absolute = [truth[k].compose(gtsam.Pose2.Expmap(rng.normal(0, abs_sigma))) for k in rows]
    return t, truth, odo, rows, absolute


def as_pose3(poses2) -> list[gtsam.Pose3]:
    return [gtsam.Pose3(gtsam.Rot3.Yaw(p.theta()), np.array([p.x(), p.y(), 0.0])) for p in poses2]


def test_planar_robot_tracks_within_5_cm_and_0_35_of_the_dead_reckoning_error(workspace):
    t, truth, odo, rows, absolute = planar_dataset(np.random.default_rng(5))
    sources = [workspace.poses("odom", t, as_pose3(odo)), workspace.poses("gnss", t[rows], as_pose3(absolute))]
    workspace.poses("truth", t, as_pose3(truth))
    config = {"robots": {"rover": {"description": {"name": "rover"}, "states": {"stream": "odom", "type": "pose2"}}},
              "sources": sources,
              "factors": [{"type": "pose.relative", "robot": "rover", "stream": "odom",
                           "sigma": {"rotation": 0.003, "translation": 0.01}},
                          {"type": "pose.absolute", "robot": "rover", "stream": "gnss",
                           "sigma": {"rotation": 0.01, "translation": 0.02}}],
              "initializers": [{"type": "pose.dead_reckoning", "robot": "rover", "stream": "odom", "anchor": "gnss"}],
              "truth": {"trajectories": {"rover": "truth.tum"}}}
    result = fusionkit.run(workspace.config(config))
    problem, values = result.problem, result.solution.values
    assert problem.keys.get("rover", "pose").vartype is POSE2
    assert all(r.factor.dim() == 3 for r in problem.records)
    est = [values.atPose2(problem.states["rover"].key(k)) for k in range(len(t))]
    err = np.array([POSE2.local(a, b) for a, b in zip(truth, est)])
    dead = [absolute[0]]
    for a, b in zip(odo[:-1], odo[1:]):
        dead.append(dead[-1].compose(a.between(b)))
    dead_err = np.linalg.norm([[p.x() - q.x(), p.y() - q.y()] for p, q in zip(truth, dead)], axis=1)
    position_rmse = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))))
    ev = result.evaluation["trajectories"]["rover"]
    assert ev["matched_poses"] == len(t)
    # the Pose3 report of the Pose2 states (truth file: 9 decimals)
    assert ev["ate_rmse_m"] == pytest.approx(position_rmse, abs=1e-6)
    # measured (seed 5): 3.5 cm fused vs 12.7 cm dead reckoning; heading 0.008 rad
    assert position_rmse < 0.05
    assert position_rmse < 0.35 * np.sqrt(np.mean(dead_err ** 2))
    assert np.sqrt(np.mean(err[:, 2] ** 2)) < 0.015  # heading, rad
    # the position sigmas are honest: most errors inside 2 sigma
    assert result.evaluation["trajectories"]["rover"]["consistency_percent"]["x"]["2sigma"] > 80
    assert result.trajectories["rover"].pose_array()[:, 2].max() == 0.0


# --- a time-varying parameter, tied to data by a test-local plugin ---------------------------------

class DirectMeasurement(FactorType):
    """A sensor reading a (possibly time-varying) scalar parameter directly: z = p[k] + noise."""

    name = "test.direct"
    summary = "direct noisy readings of a scalar robot parameter"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "parameter": {"type": "string"}, "column": {"type": "string"},
                             "sigma": {"type": "number", "exclusiveMinimum": 0}},
              "required": ["robot", "stream", "parameter", "column", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_parameter(spec, "robot", "parameter", "scalar")
        scope.require_columns(spec, "stream", (spec["column"],))

    def build(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot, 0.005, spec)
        noise = ctx.noise([spec["sigma"]], spec)
        for k, z in zip(assoc.state.tolist(), stream.column(spec["column"])[assoc.row].tolist()):
            key = ctx.parameter(robot, spec["parameter"], k=k)  # static parameters ignore k
            ctx.add(gtsam.PriorFactorDouble(key, z, noise), spec, ctx.state_time(robot, k))

    @classmethod
    def example(cls, rng):
        p = float(rng.normal())
        values = gtsam.Values()
        values.insert(0, p)
        return FactorExample(gtsam.PriorFactorDouble(0, p, gaussian([0.1])), values)


class DirectPlugin:
    @fusionkit.api.hookimpl
    def register_factor_types(self):
        return [DirectMeasurement]


def test_the_test_factor_type_keeps_the_contract():
    check_factor_contract(DirectMeasurement)


def drifting_quantity(t: np.ndarray) -> np.ndarray:
    return 1.0 + 0.5 * np.sin(2 * np.pi * t / 30.0) + 0.3 * t / t[-1]


def test_time_varying_parameter_tracks_a_drift_to_0_05_rmse_with_honest_sigmas(workspace, use_plugins):
    reg = use_plugins(DirectPlugin())
    assert reg.provider[("factor_types", "test.direct")] == "test_plugin_0"
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 60.0, 0.1)
    truth = drifting_quantity(t)
    readings = truth + rng.normal(0.0, 0.1, len(t))
    sources = [workspace.columns("gauge", t, reading=readings)]

    def config(time_varying: bool) -> dict:
        factors = [{"type": "test.direct", "robot": "rig", "stream": "gauge", "parameter": "offset",
                    "column": "reading", "sigma": 0.1}]
        if time_varying:
            factors.append({"type": "parameter.random_walk", "robot": "rig", "parameter": "offset", "sigma": 0.05})
        offset = {"type": "scalar", "value": 0.0, "sigma": 10.0, "time_varying": time_varying}
        return {"robots": {"rig": {"description": {"name": "rig", "parameters": {"offset": offset}},
                                   "states": {"stream": "gauge"}}},
                "sources": sources, "factors": factors,
                # a constant cannot explain the drift: accept its large residual to compare
                "solver": {"type": "batch", "max_cost_ratio": 10.0 if time_varying else 1e3}}

    tv = fusionkit.run(workspace.config(config(True), "tv.yaml"))
    const = fusionkit.run(workspace.config(config(False), "const.yaml"))
    est = tv.parameters["rig"]["offset"]
    assert est.family.kind == TIME_VARYING and len(est.values) == len(t)
    np.testing.assert_allclose(est.series_t, t, atol=1e-9)
    assert est.sigma.shape == (len(t), 1)
    assert tv.trajectories == {}  # the robot has states but no poses
    err = np.asarray(est.values) - truth
    (c,) = const.parameters["rig"]["offset"].values
    assert c == pytest.approx(np.mean(readings), abs=1e-4)  # the constant fit is the mean reading
    tv_rmse, const_rmse = np.sqrt(np.mean(err ** 2)), np.sqrt(np.mean((c - truth) ** 2))
    assert const_rmse > 0.3
    assert tv_rmse < 0.05 and tv_rmse < 0.15 * const_rmse
    z = np.abs(err) / est.sigma[:, 0]
    assert 0.85 < np.mean(z < 2) <= 1.0  # the per-state sigmas are honest
    # the readings alone scatter by 0.1; the random walk smooths them
    assert tv_rmse < 0.5 * 0.1
