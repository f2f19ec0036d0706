"""The e-puck factors: the contract (the motion factor on a straight line and on an arc), the IR
factor's censored rows and log-variance term against central differences and against the
likelihoods they stand for, one evaluator per entry returning each factor's own result, and bad
descriptions and entries as one located line (inline descriptions: their own key paths, at the
config's lines)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.stats import norm

from fusionkit.api import robot_description_data
from fusionkit.cli.main import main
from fusionkit.testing import check_factor_example, numerical_jacobians
from fusionkit_plugins.epuck.evaluator import IrEntryEvaluator
from fusionkit_plugins.epuck.factors import ir_factor, velocity_example
from fusionkit_plugins.epuck.irfactor import FAR, IN, NEAR, IrModelContext, ReadingSet, censored_residual
from fusionkit_plugins.epuck.model import shipped_layout
from fusionkit_plugins.epuck.walls import box_walls, ray_distances


@pytest.mark.parametrize("omega", [0.0, 1.3])
def test_velocity_motion_meets_the_contract_on_a_straight_line_and_on_an_arc(omega):
    for seed in range(3):
        check_factor_example(velocity_example(np.random.default_rng(seed), omega), f"omega={omega}")


def test_censored_residual_squared_is_minus_two_log_phi_with_its_derivative_everywhere():
    u = np.array([-60.0, -8.0, -2.0, 0.0, 1.5, 6.0])
    e, de = censored_residual(u)
    np.testing.assert_allclose(e ** 2, -2.0 * norm.logcdf(-u), rtol=1e-9, atol=1e-300)
    h = 1e-6
    numeric = (censored_residual(u + h)[0] - censored_residual(u - h)[0]) / (2 * h)
    np.testing.assert_allclose(de, numeric, rtol=1e-5, atol=1e-12)
    assert np.all(np.isfinite(e)) and np.all(np.isfinite(de))


@pytest.fixture(scope="module")
def model():
    layout = shipped_layout()
    return layout, box_walls(0.12, 0.10)


def mixed_factor(model, noise: str, rng):
    """All eight sensors at a random pose in a 12 x 10 cm box: in range, beyond it and closer than it
    (kinds assigned regardless of the readings: the residual is defined for any), with gains and offsets."""
    layout, walls = model
    ctx = IrModelContext(walls, layout.mounts, layout.angles, layout.bank, noise)
    pose = np.array([rng.uniform(0.05, 0.07), rng.uniform(0.04, 0.06), rng.uniform(-np.pi, np.pi)])
    kind = np.array([IN, IN, FAR, IN, NEAR, IN, FAR, IN])
    s = np.arange(8)
    threshold = np.where(kind == NEAR, layout.bank.near_threshold, layout.bank.far_threshold)
    z = layout.bank.evaluate(ray_distances(walls, np.tile(pose, (8, 1)), layout.mounts, layout.angles)).mean
    readings = ReadingSet(s, z + rng.normal(0.0, 30.0, 8), kind, threshold, rng.uniform(2.0, 9.0, 8))
    gain, offset = rng.uniform(0.9, 1.1, 8), rng.normal(0.0, 20.0, 8)
    values = gtsam.Values()
    values.insert(0, gtsam.Pose2(*pose))
    for j, v in enumerate(np.concatenate([gain, offset])):
        values.insert(1 + j, float(v))
    evaluator = IrEntryEvaluator(ctx, [readings], [list(range(17))], (True, True))
    rows = len(readings.rows(noise)[0])
    return ir_factor(evaluator, 0, gtsam.noiseModel.Unit.Create(rows)), values, ctx, readings, pose, gain, offset


@pytest.mark.parametrize("noise", ["full", "whitened", "at_reading"])
def test_ir_factor_jacobians_with_censored_rows_and_log_variance_equal_central_differences(model, noise):
    rng = np.random.default_rng(7)
    for _ in range(3):
        factor, values, *_ = mixed_factor(model, noise, rng)
        analytic = factor.linearize(values).jacobian()[0]
        numeric = np.hstack(numerical_jacobians(factor, values))
        np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-6)


def test_full_noise_cost_is_the_gaussian_and_censored_negative_log_likelihood_up_to_a_constant(model):
    """Half the squared residual of readings at several poses minus the exact negative log-likelihood
    (N(g F_mean + o, F_var) in range; Phi for the censored) is the same constant at every pose."""
    rng = np.random.default_rng(3)
    _, _, ctx, readings, pose, gain, offset = mixed_factor(model, "full", rng)
    gaps = []
    for shift in ([0, 0, 0], [0.002, -0.001, 0.05], [-0.003, 0.002, -0.1]):
        p = pose + np.array(shift)
        e = ctx.residual(p, readings, gain, offset)
        d = ray_distances(ctx.walls, np.tile(p, (8, 1)), ctx.mounts, ctx.angles)
        ev = ctx.bank.evaluate(d)
        pred, sigma = gain * ev.mean + offset, np.sqrt(ev.var)
        inside = readings.kind == IN
        nll = np.sum(0.5 * ((readings.z - pred) / sigma) ** 2 + np.log(sigma), where=inside)
        sign = np.where(readings.kind == FAR, 1.0, -1.0)
        nll -= np.sum(norm.logcdf(-sign * (pred - readings.threshold) / sigma), where=~inside)
        gaps.append(0.5 * e @ e - nll)
    assert np.ptp(gaps) < 1e-8 * abs(gaps[0])


def test_one_evaluator_gives_each_factor_its_own_result_when_values_change_one_by_one(model):
    """Two states' factors share an evaluator: moving one pose changes only that factor's residual."""
    layout, walls = model
    ctx = IrModelContext(walls, layout.mounts, layout.angles, layout.bank, "full")
    poses = [np.array([0.06, 0.05, 0.3]), np.array([0.055, 0.052, -0.4])]
    sets = []
    for p in poses:
        z = layout.bank.evaluate(ray_distances(walls, np.tile(p, (8, 1)), layout.mounts, layout.angles)).mean
        kind = np.where(z < layout.bank.far_threshold, FAR, IN)
        sets.append(ReadingSet(np.arange(8), z + 3.0, kind, layout.bank.far_threshold, np.ones(8)))
    evaluator = IrEntryEvaluator(ctx, sets, [[0], [1]], (False, False))
    factors = [ir_factor(evaluator, i, gtsam.noiseModel.Unit.Create(len(r.rows("full")[0])))
               for i, r in enumerate(sets)]
    values = gtsam.Values()
    for i, p in enumerate(poses):
        values.insert(i, gtsam.Pose2(*p))
    before = [f.unwhitenedError(values) for f in factors]
    values.update(1, gtsam.Pose2(*(poses[1] + [0.001, 0.0, 0.02])))
    after = [f.unwhitenedError(values) for f in factors]
    np.testing.assert_array_equal(after[0], before[0])
    direct = ctx.residual(poses[1] + [0.001, 0.0, 0.02], sets[1], np.ones(8), np.zeros(8))
    np.testing.assert_allclose(after[1], direct, rtol=1e-12)
    assert not np.allclose(after[1], before[1])


def config_with(puck: dict, arena: dict | None = None, ir: dict | None = None) -> dict:
    return {"name": "bad_epuck",
            "robots": {"arena": {"description": arena or robot_description_data("epuck_arena")},
                       "puck": {"description": puck, "states": {"stream": "ir", "type": "pose2"}}},
            "sources": [{"type": "simulate", "scenario": "epuck.sim", "params": {"duration": 2.0}}],
            "factors": [{"type": "pose.origin", "robot": "puck", "pose": [0.1, 0.06, 0.0],
                         "sigma": {"rotation": 0.03, "translation": 0.003}},
                        {"type": "epuck.velocity_motion", "robot": "puck", "stream": "commands"},
                        {"type": "epuck.ir", "robot": "puck", "map": "arena", "stream": "ir", **(ir or {})}]}


def puck_with(change) -> dict:
    data = robot_description_data("epuck")
    change(data)
    return data


CASES = {
    "zero-width term": (config_with(puck_with(lambda d: d["sensors"]["ir2"]["mean"][1].__setitem__(2, 0.0))),
                        "sensors.ir2.mean[1][2]: c = 0"),
    "no variance model": (config_with(puck_with(lambda d: d["sensors"]["ir5"].pop("variance"))),
                          "sensors.ir5: an ir_proximity sensor needs `variance:`"),
    "negative variance": (config_with(puck_with(lambda d: d["sensors"]["ir0"].update(variance=[[-5.0, 3.0, 2.0]]))),
                          "sensors.ir0.variance: the variance model is not positive"),
    "drop-out probability 1": (config_with(puck_with(lambda d: d["sensors"]["ir3"].update(dropout=1.0))),
                               "sensors.ir3.dropout: 1.0: expected a probability in [0, 1)"),
    "negative saturation": (config_with(puck_with(lambda d: d["sensors"]["ir1"].update(saturation=-5))),
                            "sensors.ir1.saturation: -5: expected the reading (counts, > 0) the sensor clips at"),
    "five alphas": (config_with(puck_with(lambda d: d["velocity_noise"]["alpha"].append(0.01))),
                    "velocity_noise.alpha: 5 values"),
    "zero-length wall": (config_with(robot_description_data("epuck"),
                                     {**robot_description_data("epuck_arena"), "segments": [[[0, 0], [0, 0]]]}),
                         "segments[0]: [[0, 0], [0, 0]]: a segment of zero length"),
    "unknown sensor": (config_with(robot_description_data("epuck"), ir={"sensors": ["ir9"]}),
                       "factors[2].sensors: 'ir9' is not an ir_proximity sensor of robot 'puck'"),
    "gain without one value per sensor": (
        config_with(puck_with(lambda d: d.setdefault("parameters", {}).update(
            ir_gain={"type": "scalar", "values": [1.0, 1.0], "sigma": 0.1})), ir={"gain": "ir_gain"}),
        "factors[2].gain: puck/ir_gain has 2 value(s); expected one per IR sensor of the robot (8"),
}


@pytest.mark.parametrize("case", CASES)
def test_bad_epuck_description_or_entry_is_one_located_line(case, workspace, capsys):
    data, expected = CASES[case]
    assert main(["validate", str(workspace.config(data))]) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1 and "Traceback" not in err, err
