"""report.html: one self-contained page beside report.json -- the solver's figures, every parameter with its
sigma and error against truth, trajectory errors with their sigma consistency, the run's plots embedded (no
file or network reference), the diagnostics' verdicts and the notes; without plots it says so."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from fusionkit.cli.main import main

REPO = Path(__file__).resolve().parents[2]
ERROR_HEADERS = {  # every column of an error, with its unit
    "error vs truth (unit of the estimate; poses: rad and m)", "error / sigma (per axis, no unit)",
    "ATE RMSE (m)", "RPE per step (m / deg)", "inside 1/2/3 sigma (%; ideal 68/95/99.7)"}


@pytest.mark.parametrize("plots", [True, False])
def test_report_html_holds_the_reports_figures_and_embeds_the_plots(ds, tmp_path, plots):
    out = tmp_path / "out"
    assert main(["run", str(ds / "config.yaml"), "--out", str(out)] + ([] if plots else ["--no-plots"])) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    report = json.loads((out / "report.json").read_text())
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert f"{report['solver']['chi2_per_dof']:.3g}" in page
    for robot, params in report["parameters"].items():
        for name in params:
            assert f"{robot}/{name}" in page
    ate = report["evaluation"]["trajectories"]["cam"]["ate_rmse_m"]
    assert f"<td>{ate:.4f} (align none)</td>" in page and "<th>ATE RMSE (m)</th>" in page  # the unit in its header
    assert "inside 1/2/3 sigma" in page
    for note in report["notes"]:
        assert note.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("'", "&#x27;") \
            .replace('"', "&quot;") in page
    images = re.findall(r"src='([^']*)'", page)
    assert all(src.startswith("data:image/png;base64,") for src in images)  # nothing outside the page
    assert not re.search(r"(href|src)=['\"](?!data:)", page)
    if plots:
        assert len(images) == len(list((out / "plots").glob("*.png"))) >= 2
    else:
        assert not images and "Plots were not made" in page


def _header_rows(page: str) -> list[list[str]]:
    """The cells of every table row that holds a <th>."""
    return [re.findall(r"<th>(.*?)</th>", row) for row in re.findall(r"<tr>(.*?)</tr>", page) if "<th" in row]


def test_report_html_has_no_empty_header_row_and_a_unit_on_every_error_column(tmp_path):
    """uwb_time_varying (10 s): static anchors with truth, four time-varying biases, a trajectory with truth. The
    solver's name/value table has no title row (it had one of two empty <th>); each error column says its unit;
    each time-varying bias is one row summing up its series, as the console does."""
    out = tmp_path / "out"
    assert main(["run", str(REPO / "configs" / "uwb_time_varying.yaml"), "--out", str(out), "--no-plots", "-q",
                 "--set", "sources.0.params.duration=10"]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    heads = _header_rows(page)
    assert heads and all(cell.strip() for row in heads for cell in row)
    errors = {cell for row in heads for cell in row if re.search(r"error|ATE|RPE|inside", cell)}
    assert errors == ERROR_HEADERS
    report = json.loads((out / "report.json").read_text())
    for i in range(4):
        series = report["parameters"]["a"][f"uwb_bias[{i}]"]["series"]
        first, low = series["values"][0], min(series["values"])
        assert (f"<tr><td>a/uwb_bias[{i}]</td><td>time-varying over {len(series['t'])} states, first {first:.5g} ± "
                f"{series['sigma'][0][0]:.2g} m, ") in page
        assert f", range {low:.5g}..{max(series['values']):.5g} m</td><td>-</td><td>-</td></tr>" in page
