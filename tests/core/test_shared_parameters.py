"""A robot's parameter declared as another robot's (`robots.<name>.shared: {parameter: robot/parameter}`): one
variable in the graph with the owner's value and prior, the factors of both robots on it, reported under the owner
with a note; a chain of shares ends at the owner; a missing parameter, a type or size mismatch, a time-varying
parameter and a cycle are refused in one located line."""

from __future__ import annotations

import pytest

from fusionkit.errors import ConfigError
from fusionkit.pipeline import build_problem, estimate, read_sources
from fusionkit.simulate import simulated_config

TWO = {"robots": 2, "duration": 10.0, "bias_model": "constant", "bias_drift": 0.0}


def shared(mapping: dict):
    def edit(config):
        for robot, entries in mapping.items():
            config["robots"][robot]["shared"] = entries
    return edit


def test_a_shared_parameter_is_one_variable_used_by_both_robots_and_reported_under_its_owner():
    with simulated_config("uwb.sim", TWO, seed=0, edit=shared({"b": {"uwb_bias": "a/uwb_bias"}})) as config:
        streams, _ = read_sources(config)
        problem = build_problem(config, streams)
        result = estimate(config)
    names = {problem.keys.name_of(k) for r in problem.records if r.label.endswith("uwb.range") for k in r.factor.keys()}
    assert any(n.startswith("a/uwb_bias") for n in names) and not any(n.startswith("b/uwb_bias") for n in names)
    assert "uwb_bias" in result.parameters["a"] and "uwb_bias" not in result.parameters.get("b", {})
    assert any("parameter 'uwb_bias' is a/uwb_bias (shared)" in n for n in result.notes)


def test_a_chain_of_shares_ends_at_the_owner():
    def third(config):
        config["robots"]["c"] = dict(config["robots"]["b"])  # a third robot like b
        shared({"b": {"uwb_bias": "a/uwb_bias"}, "c": {"uwb_bias": "b/uwb_bias"}})(config)
    with simulated_config("uwb.sim", TWO, seed=0, edit=third) as config:
        assert config.robots["c"].shared == {"uwb_bias": ("a", "uwb_bias")}


@pytest.mark.parametrize("mapping, message", [
    ({"b": {"lever": "a/uwb_bias"}}, r"robots\.b\.shared\.lever: robot 'b' has no parameter 'lever'"),
    ({"b": {"uwb_bias": "a/nothing"}}, r"robots\.b\.shared\.uwb_bias: 'a/nothing': no such robot parameter"),
    ({"b": {"uwb_bias": "anchors/anchor"}}, r"robots\.b\.shared\.uwb_bias: b/uwb_bias is 4 scalar, "
                                            r"anchors/anchor is 4 point2: a shared parameter has one type and size"),
    ({"a": {"uwb_bias": "b/uwb_bias"}, "b": {"uwb_bias": "a/uwb_bias"}}, r"the shared parameters form a cycle"),
])
def test_a_bad_share_is_one_located_error(mapping, message):
    with pytest.raises(ConfigError, match=message):
        with simulated_config("uwb.sim", TWO, seed=0, edit=shared(mapping)):
            pass


def test_a_time_varying_parameter_cannot_be_shared():
    drifting = {"robots": 2, "duration": 5.0, "bias_model": "time_varying"}
    with pytest.raises(ConfigError, match=r"robots\.b\.shared\.uwb_bias: a time-varying parameter .* cannot be shared"):
        with simulated_config("uwb.sim", drifting, seed=0, edit=shared({"b": {"uwb_bias": "a/uwb_bias"}})):
            pass
