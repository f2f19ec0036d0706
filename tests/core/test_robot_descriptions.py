"""Robot descriptions shipped as package data (hook `register_robot_descriptions`): a config names one
by name (`description: arascam`), a path still loads a file, an unknown name is one located line
listing the registered names, and a plugin's malformed or clashing registration is left out."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

import fusionkit
import fusionkit.api
from fusionkit.api import robot_description_data
from fusionkit.cli.main import main
from fusionkit.errors import ConfigError
from fusionkit.plugins import registry

REPO = Path(__file__).resolve().parents[2]
QUICKSTART = REPO / "configs" / "quickstart.yaml"
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
SHIPPED = sorted((REPO / "robots").glob("*/*.yaml"), key=lambda p: p.stem)


class DescriptionPlugin:
    """A plugin registering the given {name: file}."""

    def __init__(self, files: dict):
        self.files = files

    @fusionkit.api.hookimpl
    def register_robot_descriptions(self):
        return self.files


def test_every_shipped_description_is_registered_under_its_file_name_which_is_its_name():
    assert registry().names("robot_descriptions") == sorted(p.stem for p in SHIPPED)
    assert [yaml.safe_load(p.read_text())["name"] for p in SHIPPED] == [p.stem for p in SHIPPED]


def test_a_name_loads_the_packaged_file():
    desc = fusionkit.load_config(QUICKSTART).robots["cdpr"].description
    shipped = REPO / "robots" / "cable_rigid" / "arascam.yaml"
    assert desc.doc.file == shipped
    pulleys = [list(p) for p in desc.parameters["pulley"].values]
    assert pulleys == yaml.safe_load(shipped.read_text())["parameters"]["pulley"]["values"]


def test_unknown_name_is_one_located_line_listing_the_registered_names(capsys):
    assert main(["validate", str(QUICKSTART), "--set", "robots.cdpr.description=arascm"]) == 2
    err = capsys.readouterr().err
    names = ", ".join(p.stem for p in SHIPPED)
    assert err == (f"fusionkit: error: {QUICKSTART}: robots.cdpr.description: unknown robot description 'arascm'; "
                   f"installed: {names} (see `fusionkit plugins`); a description file is given by its path "
                   "(e.g. ./arascm.yaml) (from --set robots.cdpr.description=arascm)\n")


@pytest.mark.parametrize("source", ["arascam.yaml", "robots/arascam", "arascam.YML"])
def test_a_path_separator_or_yaml_suffix_makes_it_a_file_path(capsys, source):
    assert main(["validate", str(QUICKSTART), "--set", f"robots.cdpr.description={source}"]) == 2
    err = capsys.readouterr().err
    assert f"robots.cdpr.description: robot description file not found: {QUICKSTART.parent / source} " in err


def test_a_plugins_description_is_loaded_by_name_and_listed(use_plugins, tmp_path, capsys):
    file = tmp_path / "rig.yaml"
    file.write_text((REPO / "robots" / "pose" / "handheld_camera.yaml").read_text()
                    .replace("value: 1.0", "value: 2.5"))
    use_plugins(DescriptionPlugin({"rig": file}))
    desc = fusionkit.load_config(SCALED_VO, ["robots.cam.description=rig"]).robots["cam"].description
    assert desc.doc.file == file and desc.parameters["vo_scale"].values == [2.5]
    assert robot_description_data("rig")["parameters"]["vo_scale"]["value"] == 2.5
    assert main(["plugins"]) == 0
    assert "  description  rig " in capsys.readouterr().out
    assert main(["plugins", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["test_plugin_0"] == {"robot_descriptions": [
        {"name": "rig", "summary": "monocular camera whose visual odometry has an unknown scale, with a mocap marker",
         "file": str(file)}]}


@pytest.mark.parametrize("files, reason", [
    (lambda tmp: {"arascam": tmp / "rig.yaml"}, "robot description 'arascam' is already provided by "
                                                "cable_rigid"),
    (lambda tmp: {"rig.yaml": tmp / "rig.yaml"}, "returned the name 'rig.yaml'; expected a name without a path "
                                                 "separator or .yaml/.yml suffix"),
    (lambda tmp: {"rig": tmp / "missing.yaml"}, "for 'rig'; expected an existing file"),
    (lambda tmp: [tmp / "rig.yaml"], "expected {name: file}"),
])
def test_a_malformed_or_clashing_registration_leaves_the_plugin_out(use_plugins, tmp_path, files, reason):
    (tmp_path / "rig.yaml").write_text("name: rig\n")
    reg = use_plugins(DescriptionPlugin(files(tmp_path)))
    assert len(reg.broken) == 1 and reg.broken[0].startswith("plugin test_plugin_0: ") and reason in reg.broken[0]
    assert "rig" not in reg.names("robot_descriptions")
    assert reg.provider[("robot_descriptions", "arascam")] == "cable_rigid"


def test_description_data_is_a_fresh_dict_and_an_unknown_name_lists_the_registered_ones():
    first = robot_description_data("arascam")
    first["parameters"]["pulley"]["values"][0][0] = 99.0
    assert robot_description_data("arascam")["parameters"]["pulley"]["values"][0][0] == -2.0
    with pytest.raises(ConfigError, match=r"^unknown robot description 'nope'; installed: arascam, arash_asist, "
                                          r"arash_asist_mm, cdpr_large, "):
        robot_description_data("nope")


def test_the_reference_lists_every_shipped_description_with_its_summary():
    text = (REPO / "docs" / "reference" / "robot_description.md").read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \| \w+ \| \w+ \| (.+) \|$", text, re.M))
    assert rows == {n: robot_description_data(n)["summary"] for n in registry().names("robot_descriptions")}


def test_a_shipped_description_of_another_model_is_one_located_config_error():
    assert robot_description_data("epuck", "epuck")["model"] == "epuck"
    with pytest.raises(ConfigError, match=r"^wheels.sim: description 'epuck' is a 'epuck' robot; expected a "
                                          r"diff_drive one$"):
        robot_description_data("epuck", "diff_drive", "wheels.sim")
