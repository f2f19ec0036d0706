"""A robot whose states are not poses: a 2-D position vector per state (a cart on rails, a joint pair),
through the whole pipeline -- config, a plugin written against fusionkit.api only, solve, the series
file, report.json, evaluation against true states -- at a stream's stamps and at a fixed rate."""

from __future__ import annotations

import json

import gtsam
import numpy as np
import pytest

from fusionkit.api import FactorExample, FactorType, Spec, gaussian, hookimpl, nearest, vector_type
from fusionkit.cli.main import main

VEC2 = vector_type(2)
NOISE_STEP, NOISE_FIX = 0.02, 0.05  # m per increment, m per absolute fix


class VectorIncrements(FactorType):
    """x_k+1 - x_k = the increment measured between consecutive states (native BetweenFactorVector)."""

    name = "test.vector_increments"
    summary = "increments of a vector state between consecutive states"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object", "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                                                "sigma": {"type": "number", "exclusiveMinimum": 0}},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "vector2")

    def build(self, ctx, spec: Spec) -> None:
        robot, stream = spec["robot"], ctx.stream(spec["stream"])
        states = ctx.state_set(robot, spec)
        position = np.column_stack([stream.column("x"), stream.column("y")])
        at = np.array([np.interp(states.t, stream.t, position[:, i]) for i in range(2)]).T
        noise = ctx.noise([spec["sigma"]] * 2, spec)
        for k in range(1, len(states)):
            ctx.add(gtsam.BetweenFactorVector(ctx.state_key(robot, k - 1), ctx.state_key(robot, k),
                                              at[k] - at[k - 1], noise), spec, ctx.state_time(robot, k))

    @classmethod
    def example(cls, rng):
        a, d = rng.normal(size=2), rng.normal(size=2)
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, a + d)
        return FactorExample(gtsam.BetweenFactorVector(0, 1, d, gaussian([0.1, 0.1])), values)


class VectorFix(FactorType):
    """An absolute measurement of the vector state at the nearest state."""

    name = "test.vector_fix"
    summary = "absolute fixes of a vector state"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = VectorIncrements.schema

    def build(self, ctx, spec: Spec) -> None:
        robot, stream = spec["robot"], ctx.stream(spec["stream"])
        a = nearest(ctx.state_set(robot, spec).t, stream.t, 0.01)
        noise = ctx.noise([spec["sigma"]] * 2, spec)
        for k, row in zip(a.state, a.row):
            z = np.array([stream.column("x")[row], stream.column("y")[row]])
            key = ctx.state_key(robot, int(k))
            ctx.add(gtsam.PriorFactorVector(key, z, noise), spec, ctx.state_time(robot, int(k)))
            ctx.set_initial(key, z)

    @classmethod
    def example(cls, rng):
        a = rng.normal(size=2)
        values = gtsam.Values()
        values.insert(0, a)
        return FactorExample(gtsam.PriorFactorVector(0, a, gaussian([0.1, 0.1])), values)


class VectorPlugin:
    @hookimpl
    def register_factor_types(self):
        return [VectorIncrements, VectorFix]


@pytest.fixture
def cart(workspace):
    """A cart wandering in the plane for 20 s: increments at 10 Hz (odometry), fixes at 1 Hz, truth."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 20.0, 0.1)
    truth = np.cumsum(rng.normal(0.0, 0.05, (len(t), 2)), axis=0)
    odom = truth + np.cumsum(rng.normal(0.0, NOISE_STEP, (len(t), 2)), axis=0)  # integrated: drifts
    fixes = np.arange(0, len(t), 10)
    fix = truth[fixes] + rng.normal(0.0, NOISE_FIX, (len(fixes), 2))
    sources = [workspace.columns("odom", t, x=odom[:, 0], y=odom[:, 1]),
               workspace.columns("fix", t[fixes], x=fix[:, 0], y=fix[:, 1])]
    workspace.columns("truth", t, c0=truth[:, 0], c1=truth[:, 1])

    def config(states: dict, **extra) -> dict:
        return {"name": "cart", "robots": {"cart": {"description": {"name": "cart"}, "states": states}},
                "sources": sources,
                "factors": [{"type": "test.vector_increments", "robot": "cart", "stream": "odom", "sigma": NOISE_STEP},
                            {"type": "test.vector_fix", "robot": "cart", "stream": "fix", "sigma": NOISE_FIX}],
                "truth": {"states": {"cart": {"position": "truth.csv"}}}, **extra}
    return workspace, config, t, truth


def test_vector_states_are_solved_written_and_evaluated_against_truth(cart, use_plugins, capsys):
    use_plugins(VectorPlugin())
    workspace, config, t, truth = cart
    path = workspace.config(config({"stream": "odom", "type": "vector2", "family": "position"}))
    out = workspace.folder / "out"
    assert main(["run", str(path), "--out", str(out), "-q"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["states"]["cart"]["position"] == {"type": "vector2", "count": 200, "components": ["c0", "c1"],
                                                    "file": "states/cart.position.csv"}
    assert not (out / "trajectories").exists()  # no pose states, no TUM file
    table = np.loadtxt(out / "states" / "cart.position.csv", delimiter=",", skiprows=1)
    header = (out / "states" / "cart.position.csv").read_text().splitlines()[0]
    assert header == "t,c0,c1,sigma_c0,sigma_c1" and table.shape == (200, 5)
    np.testing.assert_allclose(table[:, 0], t, atol=1e-9)
    rmse = np.sqrt(np.mean((table[:, 1:3] - truth) ** 2, axis=0))
    ev = report["evaluation"]["states"]["cart"]["position"]
    assert ev["matched"] == 200 and ev["rmse_per_axis"] == pytest.approx(rmse.tolist(), rel=1e-6)
    assert rmse.max() < 0.05  # between the fixes' 5 cm and the odometry's drift
    for axis in ("c0", "c1"):  # the smoother's sigmas against its own errors (1 run: a loose band)
        share = ev["consistency_percent"][axis]
        assert 45 < share["1sigma"] < 90 and share["3sigma"] > 97


def test_states_at_a_fixed_rate_span_the_named_stream(cart, use_plugins, capsys):
    use_plugins(VectorPlugin())
    workspace, config, t, truth = cart
    path = workspace.config(config({"stream": "odom", "rate": 2.0, "type": "vector2", "family": "position"}))
    out = workspace.folder / "rate"
    assert main(["run", str(path), "--out", str(out), "-q", "--no-plots"]) == 0
    table = np.loadtxt(out / "states" / "cart.position.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 0], np.arange(0.0, 19.91, 0.5), atol=1e-9)  # 0 .. 19.9 s at 2 Hz
    ev = json.loads((out / "report.json").read_text())["evaluation"]["states"]["cart"]["position"]
    assert ev["matched"] == 40 and max(ev["rmse_per_axis"]) < 0.06


@pytest.mark.parametrize("states, needle", [
    ({"stream": "odom", "type": "vector0"}, "robots.cart.states.type: unknown variable type 'vector0'"),
    ({"rate": 2.0}, "robots.cart.states: expected `stream:` (one state per sample), or `rate:` (Hz) with"),
    ({"stream": "odom", "rate": 2.0, "every": 2}, "robots.cart.states.every: `every` thins a stream's stamps"),
    ({"rate": 2.0, "start": 5.0, "end": 1.0}, "robots.cart.states.end: end 1.0 is not after start 5.0"),
])
def test_bad_state_clocks_are_one_located_line(cart, use_plugins, capsys, states, needle):
    use_plugins(VectorPlugin())
    workspace, config, _, _ = cart
    path = workspace.config(config(states))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
