"""report.html: one self-contained page (inline style, plots embedded as data URIs, no network) beside
report.json: the solver's summary, parameters with sigmas and errors against truth, trajectory errors and
their sigma consistency, the plots, the diagnostics' verdicts and the notes."""

from __future__ import annotations

import base64
from html import escape
from pathlib import Path

from .. import __version__
from ..pipeline import RunResult
from ..solve.noise_scales import scale_text
from .summary import analysis_lines, parameter_rows

STYLE = """body{font-family:system-ui,sans-serif;margin:2em auto;max-width:70em;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}
th{background:#f3f3f3}.bad{color:#b00;font-weight:bold}.small{color:#666;font-size:.9em}
img{max-width:100%;border:1px solid #ddd;margin:.5em 0}li{margin:.2em 0}"""


def _table(head: list[str] | None, rows: list[list[str]]) -> str:
    """A table with the column titles `head` (None: a two-column list of name and value, no title row)."""
    cells = "" if head is None else "<tr>" + "".join(f"<th>{escape(h)}</th>" for h in head) + "</tr>"
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>{cells}{body}</table>"


def _solver(result: RunResult) -> str:
    s = result.solution
    rows = [["solver", escape(s.solver)], ["iterations / steps", str(s.iterations)],
            ["cost", f"{s.initial_error:.4g} &rarr; {s.final_error:.4g}"],
            ["chi-square per degree of freedom", "-" if s.chi2_per_dof is None else f"{s.chi2_per_dof:.3g}"],
            ["solve time", f"{s.seconds:.3f} s"]]
    if s.rejection:
        rows.append(["status", f"<span class=bad>REJECTED</span>: {escape(str(s.rejection))}"])
    for w in s.warnings:
        rows.append([f"warning [{escape(w.name)}]", escape(w.text().split(": ", 1)[1])])
    for label, fit in (s.noise_scales or {}).items():
        rows.append([f"noise scale of {escape(label)}", escape(scale_text(fit))])
    latency = s.stats().get("step_latency_ms")
    if latency:
        rows.append(["per-step latency", f"p50 {latency['p50']:.3f} ms, p99 {latency['p99']:.3f} ms"])
    return _table(None, rows)


def _parameters(result: RunResult) -> str:
    """The summary's parameter rows (summary.parameter_rows) with their errors against truth: an error in the
    estimate's unit (the description's `unit:` beside it where it gives one), error / sigma per tangent axis."""
    errors = result.evaluation.get("parameters", {})
    rows = []
    for row in parameter_rows(result):
        err = {} if row.series else errors.get(row.robot, {}).get(row.name, {})
        unit = _unit(result, row.robot, row.name)
        truth = f"{err['abs_error'][row.index]:.3g}{unit}" if "abs_error" in err else "-"
        if "aligned_abs_error" in err:
            truth += f" (aligned {err['aligned_abs_error'][row.index]:.3g}{unit})"
        z = err.get("z_per_axis")
        zs = ", ".join(f"{x:+.2f}" for x in z[row.index]) if z else "-"
        rows.append([escape(row.label), escape(row.text), escape(truth), zs])
    if not rows:
        return "<p>No parameters estimated.</p>"
    return _table(["parameter", "estimate ± 1-sigma", "error vs truth (unit of the estimate; poses: rad and m)",
                   "error / sigma (per axis, no unit)"], rows) + (
        "<p class=small>The error of a pose (rotation) is the norm of its tangent-space error, rad and m together; "
        "time-varying parameters are summed up (first, last, range), report.json has their series.</p>")


def _unit(result: RunResult, robot: str, name: str) -> str:
    setup = result.config.robots.get(robot)
    param = None if setup is None else setup.description.parameters.get(name.split("[")[0])
    return f" {param.unit}" if param is not None and param.unit else ""


def _trajectories(result: RunResult) -> str:
    rows = []
    for robot, ev in result.evaluation.get("trajectories", {}).items():
        ate = f"{ev['ate_rmse_m']:.4f} (align {escape(ev['align'])})" if "ate_rmse_m" in ev else "-"
        rpe = (f"{ev['rpe_translation_rmse_m']:.4f} / {ev['rpe_rotation_rmse_deg']:.3f}"
               if "rpe_translation_rmse_m" in ev else "-")
        c = ev.get("consistency_percent")
        within = "; ".join(f"{ax} {c[ax]['1sigma']:.0f}/{c[ax]['2sigma']:.0f}/{c[ax]['3sigma']:.0f}" for ax in c) if c else "-"
        rows.append([escape(robot), f"{ev['matched_poses']} of {ev['states']}", ate, rpe, within])
    if not rows:
        return "<p>No ground truth trajectory: no trajectory errors.</p>"
    return _table(["robot", "states matched to truth", "ATE RMSE (m)", "RPE per step (m / deg)",
                   "inside 1/2/3 sigma (%; ideal 68/95/99.7)"], rows)


def _plots(folder: Path | None) -> str:
    if folder is None or not folder.is_dir():
        return "<p class=small>Plots were not made (--no-plots).</p>"
    images = []
    for png in sorted(folder.glob("*.png")):
        data = base64.b64encode(png.read_bytes()).decode("ascii")
        images.append(f"<h3>{escape(png.stem.replace('_', ' '))}</h3><img alt='{escape(png.name)}' "
                      f"src='data:image/png;base64,{data}'>")
    return "".join(images) or "<p class=small>No plots.</p>"


_RED, _BLUE = "200,40,40", "40,80,200"  # the heat map's colours of a positive and a negative correlation
HEAT_MAP_MAX = 60  # components beyond which the page refers to report.json for the matrix


def _identifiability(result: RunResult) -> str:
    """What the data determine: the report's sentences and the parameters' correlation as a heat map (a table
    whose cells are shaded by |rho|, red for positive, blue for negative)."""
    report = result.identifiability
    analyses = analysis_lines(result.problem)
    before = f"<ul>{''.join(f'<li>{escape(line)}</li>' for line in analyses)}</ul>" if analyses else ""
    if report is None:
        return before + ("<p>Not computed: no parameters (or every axis held), more than 400 components, "
                         "solver.marginals false, or the fixed-lag smoother.</p>")
    lines = report.lines()
    text = before + (f"<ul>{''.join(f'<li>{escape(line)}</li>' for line in lines)}</ul>" if lines else (
        "<p>Every parameter is determined by the data on its own (no |rho| above 0.9, no prior that decides).</p>"))
    if len(report.names) > HEAT_MAP_MAX:
        return text + (f"<p class=small>{len(report.names)} parameter components: the correlation matrix is in "
                       "report.json (identifiability.correlation).</p>")
    short = [escape(name.split("/", 1)[1]) for name in report.names]
    head = "<tr><th>rho</th>" + "".join(f"<th class=small>{n}</th>" for n in short) + "</tr>"
    rows = []
    for name, row in zip(short, report.correlation):
        cells = "".join(f"<td class=small title='{rho:+.3f}' style='background: rgba({_RED if rho > 0 else _BLUE},"
                        f"{abs(rho):.2f})'>{rho:+.2f}</td>" for rho in row)
        rows.append(f"<tr><th class=small>{name}</th>{cells}</tr>")
    return text + f"<h3>Posterior correlation of the parameters</h3><table>{head}{''.join(rows)}</table>"


def report_html(result: RunResult, plots: Path | None) -> str:
    """The page; `plots`: the folder of this run's PNGs to embed (None without plots)."""
    verdicts = [f"<li><b>{escape(label)}</b>: {escape(sentence)}</li>"
                for label, d in result.problem.diagnostics.items() for sentence in d.get("verdict", [])]
    notes = [f"<li>{escape(note)}</li>" for note in result.notes]
    return "".join([
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>fusionkit: {escape(result.config.name)}</title><style>{STYLE}</style></head><body>",
        f"<h1>fusionkit: {escape(result.config.name)}</h1>",
        f"<p class=small>config {escape(str(result.config.doc.file))}; fusionkit {escape(__version__)}; "
        "the same figures as report.json</p>",
        "<h2>Solver</h2>", _solver(result),
        "<h2>Parameters</h2>", _parameters(result),
        "<h2>Identifiability</h2>", _identifiability(result),
        "<h2>Trajectories</h2>", _trajectories(result),
        "<h2>Plots</h2>", _plots(plots),
        "<h2>Diagnostics</h2>", f"<ul>{''.join(verdicts)}</ul>" if verdicts else "<p>None.</p>",
        "<h2>Notes</h2>", f"<ul>{''.join(notes)}</ul>" if notes else "<p>None.</p>",
        "</body></html>\n"])
