"""Mistakes in an ARASH:ASiST config or robot description are one located line and exit 2: arms of
two conventions co-registered, the wrong state type or robot model, a missing or malformed
kinematic parameter, a reversed joint range, an unknown convention, a missing column."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from fusionkit.cli.main import main

REPO = Path(__file__).resolve().parents[3]
CONFIG = REPO / "configs" / "arash_pair.yaml"
SHIPPED = REPO / "robots" / "arash" / "arash_asist.yaml"


def edited_description(folder: Path, edit) -> Path:
    data = yaml.safe_load(SHIPPED.read_text())
    edit(data)
    path = folder / "arm.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.parametrize("assignments, needle", [
    (["robots.follower.description=arash_asist_mm"],
     "factors[3].other: robot 'follower' uses convention 'authors_code', robot 'leader' 'thesis': co-registered "
     "arms must share one convention (one length unit)"),
    (["robots.leader.states.type=vector2"],
     "factors[0].robot: robot 'leader' has vector2 states; this needs vector3 (robots.leader.states.type)"),
    (["robots.leader.description=mobile_base"],
     "factors[0].robot: robot 'leader' is a 'generic' robot; rcm.joint_encoders needs a 'rcm_arm' robot"),
    (["factors.2.columns=[x, y, w]"], "factors[2].stream: stream 'leader_tip' (sources[0]) lacks column(s) w"),
])
def test_config_mistakes_are_one_located_line(capsys, assignments, needle):
    args = [a for assignment in assignments for a in ("--set", assignment)]
    assert main(["validate", str(CONFIG), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"fusionkit: error: {CONFIG}:") and needle in err, err


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d["parameters"].pop("l_1234"), "parameters: an rcm_arm needs the scalar parameter 'l_1234'"),
    (lambda d: d["parameters"]["theta"].update(type="vector2", value=[0.7, 0.1]),
     "parameters.theta: expected one scalar (`type: scalar`, `value:`); got 1 vector2 value(s)"),
    (lambda d: d["joint_limits"].update(d=[0.0, -0.027]),
     "joint_limits.d: expected [lo, hi] with lo < hi; got [0.0, -0.027]"),
    (lambda d: d.update(convention="dh"), "convention: got 'dh'; expected one of: thesis, authors_code"),
])
def test_description_mistakes_name_the_description_file_and_key(tmp_path, capsys, edit, needle):
    arm = edited_description(tmp_path, edit)
    assert main(["validate", str(CONFIG), "--set", f"robots.leader.description={arm}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"fusionkit: error: {arm}:") and needle in err, err
