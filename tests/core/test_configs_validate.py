"""Every config shipped in configs/ is runnable: it loads, reads (or generates) its data, builds
its graph, initializes, and every variable is constrained (`fusionkit validate`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fusionkit.cli.main import main

CONFIGS = sorted((Path(__file__).resolve().parents[2] / "configs").glob("*.yaml"))
# configs whose data are an external recording converted first: validated with that data by the named test
CONVERTED_DATA = {"arm_ur10_real": "tests/plugins/serial_arm/test_arm_ur10_real.py"}


def test_there_are_at_least_6_configs():
    assert len(CONFIGS) >= 6


@pytest.mark.parametrize("config", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_every_shipped_config_validates_ok(config, capsys):
    if config.stem in CONVERTED_DATA:
        pytest.skip(f"needs a converted external recording; validated by {CONVERTED_DATA[config.stem]}")
    assert main(["validate", str(config)]) == 0
    assert f"{config.name}: OK" in capsys.readouterr().out
