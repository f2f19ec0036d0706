"""Every config shipped in configs/ is runnable: it loads, reads (or generates) its data, builds
its graph, initializes, and every variable is constrained (`fusionkit validate`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fusionkit.cli.main import main

CONFIGS = sorted((Path(__file__).resolve().parents[2] / "configs").glob("*.yaml"))


def test_there_are_at_least_6_configs():
    assert len(CONFIGS) >= 6


@pytest.mark.parametrize("config", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_every_shipped_config_validates_ok(config, capsys):
    assert main(["validate", str(config)]) == 0
    assert f"{config.name}: OK" in capsys.readouterr().out
