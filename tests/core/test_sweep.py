"""`fusionkit sweep`: the runs of a sweep file (listed runs x grid x seeds), each figure read from its
report.json, gathered into sweep.csv and a summary per setting; the same numbers on 2 worker processes as in
one; a run that fails is reported and the others go on; bad sweeps are one located line."""

from __future__ import annotations

import csv
import shutil
import sys
from pathlib import Path

import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.sweep import figure, override_text, run_settings

REPO = Path(__file__).resolve().parents[2]
FIGURES = ["evaluation.parameters.cam.vo_scale.mean_abs_error", "solver.chi2_per_dof", "problem.states.cam"]


def test_settings_are_the_listed_runs_times_the_grid_times_the_seeds():
    sweep = {"runs": [{"a": 1}, {"a": 2}], "grid": {"b": [10, 20]}, "seeds": [0, 1]}
    settings = run_settings(sweep, {0: 7, 2: 0})
    assert len(settings) == 8
    assert settings[0] == {"a": 1, "b": 10, "sources.0.seed": 7, "sources.2.seed": 0}  # added to each source's
    assert settings[-1] == {"a": 2, "b": 20, "sources.0.seed": 8, "sources.2.seed": 1}
    assert run_settings({}, {}) == [{}]


def test_override_values_read_back_as_themselves():
    from fusionkit.config.overrides import apply_override
    for value in ("1e-3", "with spaces", "yes", 1e-3, 2, True, None, [1, [2.5, "x"]], {"a": 1}, float("inf")):
        data: dict = {}
        apply_override(data, f"k={override_text(value)}")
        assert data["k"] == value, (value, data["k"])


def test_figures_are_key_paths_into_the_report():
    report = {"a": {"b": [1.5, {"c": 2}]}}
    assert figure(report, "a.b.0") == 1.5 and figure(report, "a.b.1.c") == 2 and figure(report, "a.x") is None


def sweep_file(tmp_path: Path, **extra) -> Path:
    shutil.copy(REPO / "configs" / "scaled_vo_mocap.yaml", tmp_path / "base.yaml")
    (tmp_path / "robots").mkdir(exist_ok=True)
    data = {"config": "base.yaml", "seeds": [0, 1], "grid": {"sources.0.params.duration": [4.0, 6.0]},
            "figures": FIGURES, **extra}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def read_rows(folder: Path) -> list[dict]:
    with open(folder / "sweep.csv") as f:
        return list(csv.DictReader(f))


def test_a_sweep_writes_one_row_per_run_with_the_same_numbers_on_two_workers(tmp_path, capsys):
    path = sweep_file(tmp_path)
    assert main(["sweep", str(path), "--out", str(tmp_path / "two"), "--workers", "2"]) == 0
    assert main(["sweep", str(path), "--out", str(tmp_path / "one"), "--workers", "1"]) == 0
    two, one = read_rows(tmp_path / "two"), read_rows(tmp_path / "one")
    assert len(two) == 4 and all(r["status"] == "accepted" for r in two)
    assert [r[FIGURES[0]] for r in two] == [r[FIGURES[0]] for r in one]
    assert [int(r["problem.states.cam"]) for r in two] == [120, 120, 180, 180]  # 30 Hz VO over 4 s and 6 s
    summary = (tmp_path / "two" / "summary.txt").read_text()
    assert "sources.0.params.duration=4.0: 2 run(s)" in summary and "(n = 2)" in summary
    assert (tmp_path / "two" / "plots" / f"{FIGURES[0]}.png").stat().st_size > 1000


def test_a_failing_run_is_reported_and_the_others_go_on(tmp_path, capsys):
    path = sweep_file(tmp_path, runs=[{"sources.0.params.scale": 2.0}, {"sources.0.params.scale": -1.0}])
    assert main(["sweep", str(path), "--out", str(tmp_path / "res")]) == 0
    rows = read_rows(tmp_path / "res")
    assert [r["status"] for r in rows] == ["accepted"] * 4 + ["error"] * 4
    assert all("scale" in r["error"] for r in rows[4:])
    assert "4 failed" in capsys.readouterr().out


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d.update(seeds=[0], config="nothere.yaml"), "config not found"),
    (lambda d: d.pop("figures"), "'figures' is required"),
])
def test_a_bad_sweep_file_is_one_located_line(tmp_path, capsys, edit, needle):
    path = sweep_file(tmp_path)
    data = yaml.safe_load(path.read_text())
    edit(data)
    path.write_text(yaml.safe_dump(data))
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sweep.yaml" in err[0] and needle in err[0], err


def test_the_ray_backend_without_ray_says_how_to_get_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` fails, installed or not
    assert main(["sweep", str(sweep_file(tmp_path)), "--backend", "ray"]) == 2
    assert "pip install ray" in capsys.readouterr().err


def test_a_run_that_raises_an_internal_error_is_reported_not_fatal(tmp_path, monkeypatch):
    import fusionkit.pipeline
    from fusionkit.sweep import run_one

    def broken(*args, **kwargs):
        raise ValueError("a bug in one run")
    monkeypatch.setattr(fusionkit.pipeline, "estimate", broken)
    sweep_file(tmp_path)
    out = run_one(str(tmp_path / "base.yaml"), {}, FIGURES)
    assert out["status"] == "error" and out["error"] == "internal error: ValueError: a bug in one run"
    assert all(out[f] is None for f in FIGURES)
