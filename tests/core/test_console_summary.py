"""What the console says of time-varying parameters: one line per parameter with its first and last value (±
sigma), its range and its unit, instead of nothing (they were in report.json only); many are capped."""

from __future__ import annotations

from pathlib import Path

import pytest

import fusionkit
from fusionkit.pipeline import estimate
from fusionkit.report import summary
from fusionkit.report.outputs import report_document

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def uwb():
    """configs/uwb_time_varying.yaml over 10 s: four range biases (m), each one value per state (100)."""
    config = fusionkit.load_config(REPO / "configs" / "uwb_time_varying.yaml", ["sources.0.params.duration=10"])
    return estimate(config)


def test_each_time_varying_parameter_prints_first_last_and_range_with_its_unit(uwb):
    lines = summary.summary_text(uwb).splitlines()
    series = report_document(uwb)["parameters"]["a"]
    for i in range(4):
        s = series[f"uwb_bias[{i}]"]["series"]
        values, sigma = s["values"], [row[0] for row in s["sigma"]]
        assert len(values) == 100
        assert (f"  a/uwb_bias[{i}]: time-varying over 100 states, first {values[0]:.5g} ± {sigma[0]:.2g} m, "
                f"last {values[-1]:.5g} ± {sigma[-1]:.2g} m, range {min(values):.5g}..{max(values):.5g} m") in lines
    # the static anchors keep their lines, one per anchor
    assert [x.split(" = ")[0] for x in lines if x.startswith("  anchors/")] == [f"  anchors/anchor[{i}]" for i in range(4)]


def test_many_time_varying_parameters_are_capped_and_counted(uwb, monkeypatch):
    monkeypatch.setattr(summary, "MAX_SERIES", 2)
    lines = summary.summary_text(uwb).splitlines()
    assert [x.split(":")[0] for x in lines if ": time-varying over " in x] == ["  a/uwb_bias[0]", "  a/uwb_bias[1]"]
    assert "  ... and 2 more time-varying parameters (report.json has every series)" in lines
