"""The published-table sweep files (benchmarks/sweeps) are valid, and every figure they tabulate is a number
in the first run's report.json (a renamed key would otherwise show up as a blank column)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fusionkit.config.loader import load_config
from fusionkit.config.schema import validate_against
from fusionkit.config.yamlio import load_yaml
from fusionkit.sweep import SCHEMA, run_one, run_settings

SWEEPS = sorted((Path(__file__).resolve().parents[2] / "benchmarks" / "sweeps").glob("table_*.yaml"))


@pytest.mark.parametrize("file", SWEEPS, ids=[f.stem for f in SWEEPS])
def test_every_figure_of_a_published_table_sweep_is_a_number_in_its_first_run(file: Path):
    doc = load_yaml(file)
    validate_against(doc, SCHEMA, doc.data)
    config = file.parent / doc.data["config"]
    base = load_config(config)
    seeds = {i: int(s["seed"]) for i, s in enumerate(base.sources) if s.type == "simulate"}
    first = run_settings(doc.data, seeds)[0]
    result = run_one(str(config), first, doc.data["figures"])
    assert result["status"] == "accepted", result
    for figure in doc.data["figures"]:
        assert isinstance(result[figure], (int, float)), (figure, result[figure])
