"""report.html: one self-contained page beside report.json -- the solver's figures, every parameter with its
sigma and error against truth, trajectory errors with their sigma consistency, the run's plots embedded (no
file or network reference), the diagnostics' verdicts and the notes; without plots it says so."""

from __future__ import annotations

import json
import re

import pytest

from fusionkit.cli.main import main


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
    assert f"{ate:.4f} m" in page and "inside 1/2/3 sigma" in page
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
