"""Wheel calibration on real recordings (docs/models/wheels.md#real-data): the OptiOdom sessions
(../shared/data/diffdrive_optiodom: a differential drive with two wheel encoders at 20 Hz and OptiTrack
ground truth; no gyro, no passive wheel), 6 circular runs (December 2020) and 6 UMBmark squares
(June 2020).

Each parameter set (nominal; UMBmark on the squares; two-stage least squares on either session; OptiOdom's
objective reimplemented on either session; the
fusionkit graph calibration on either session -- wheels.preintegrated between states 1 s apart and the
motion-capture poses as pose.absolute; OptiOdom's published parameters) is evaluated on both
sessions with the reference implementation's measures: max e_d, the largest position error along any
run's path, and the largest final position error and heading error, dead reckoning from each run's true
start pose. A set calibrated on one session and evaluated on the other is held out. The published
figures (reference_results.csv) are in-sample. Then each session leave-one-run-out: every run
evaluated with the parameters calibrated on the session's other five (graph, least squares, OptiOdom's
objective reimplemented -- squared position errors at checkpoints every 0.5 m of travel -- and, on the
squares, UMBmark), against the in-sample figures. Then the sensitivity
of the least-squares fit to its segment length and of the graph calibration to its noise settings and
state spacing, and the graph's leave-one-run-out errors with its wheel noise lowered towards what the data
show (chi2/dof near 1) and with both entries' noise scales estimated from the data (`noise_scale: estimate`).

    python benchmarks/bench_wheels_real.py [--quick]
"""

from __future__ import annotations

import _repository  # noqa: F401,E402  (the repository root on sys.path: research/)
from research.external_data import external_data
from research.wheels_optiodom import (CIRCULAR, INCREMENTS, LONG_HORIZON, NAME, SQUARE, WheelParameters,
                                      checkpoint_fit, evaluate, graph_calibration, held_out, least_squares, load_session,
                                      nominal, published, umbmark_parameters)
from _timing import run_parts, table, timed

DATA = external_data(NAME)
SHORT = {CIRCULAR: "circular", SQUARE: "squares"}


def _published_parameters() -> dict[str, WheelParameters]:
    """OptiOdom's (Sousa et al.) published calibration of each session."""
    return {r["experiment"].replace("/", "_"): WheelParameters(float(r["Dr_m"]) / 2, float(r["Dl_m"]) / 2,
                                                               float(r["L_m"]))
            for r in published() if r["method"] == "Sousa"}


def _cells(sessions, params: WheelParameters, calibrated_on: str | None) -> list[str]:
    out = []
    for name in (CIRCULAR, SQUARE):
        e = evaluate(sessions[name], params)
        mark = "" if calibrated_on is None else (" (in)" if calibrated_on == name else " (held out)")
        out += [f"{e.max_along:.4f}{mark}", f"{e.max_final:.4f}", f"{e.max_final_heading_deg:.2f}"]
    return out


def calibrations(sessions) -> tuple[str, dict]:
    sets = {"nominal": (nominal(sessions[CIRCULAR]), None),
            "UMBmark, squares": (umbmark_parameters(sessions[SQUARE]), SQUARE),
            "least squares, circular": (least_squares(sessions[CIRCULAR]), CIRCULAR),
            "least squares, squares": (least_squares(sessions[SQUARE]), SQUARE),
            "OptiOdom objective (ours), circular": (checkpoint_fit(sessions[CIRCULAR]), CIRCULAR),
            "OptiOdom objective (ours), squares": (checkpoint_fit(sessions[SQUARE]), SQUARE)}
    graph = {}
    for objective, settings in (("long horizon", LONG_HORIZON), ("increments", INCREMENTS)):
        for on in (CIRCULAR, SQUARE):
            (params, sigma, result), seconds = timed(lambda: graph_calibration(sessions[on], settings))
            label = f"fusionkit graph ({objective}), {SHORT[on]}"
            sets[label] = (params, on)
            graph[label] = {"sigma": sigma, "seconds": seconds, "states": len(result.problem.states["robot"]),
                            "chi2_per_dof": result.solution.chi2_per_dof}
    for name, params in _published_parameters().items():
        sets[f"OptiOdom published, {SHORT[name]}"] = (params, name)
    rows, raw = [], {}
    for label, (params, on) in sets.items():
        rows.append([label, f"{params.axle_length:.6f}", f"{2 * params.radius_right:.6f}",
                     f"{2 * params.radius_left:.6f}", *_cells(sessions, params, on)])
        raw[label] = {"params": params, **{SHORT[n]: evaluate(sessions[n], params) for n in sessions}}
    head = ["parameters (calibrated on)", "L (m)", "Dr (m)", "Dl (m)", "circ max e_d", "final", "th (deg)",
            "squares max e_d", "final", "th (deg)"]
    text = table(head, rows, "OptiOdom recordings: dead reckoning with each parameter set (errors in m, deg)")
    text += "\n" + "\n".join(
        f"{on}: {g['states']} states, estimate() {g['seconds']:.2f} s, chi2/dof "
        f"{g['chi2_per_dof']:.2f}; 1-sigma r_R, r_L, A = " + ", ".join(f"{x * 1e3:.3f}" for x in g["sigma"]) + " mm"
        for on, g in graph.items())
    raw["graph"] = graph
    ref = [[f"{r['method']}, {r['experiment']}", r["L_m"], r["Dr_m"], r["Dl_m"], f"{float(r['max_ed_m']):.4f}",
            f"{float(r['max_final_ed_m']):.4f}", f"{float(r['max_final_th_deg']):.2f}"] for r in published()]
    text += "\n\n" + table(["published (in-sample)", "L (m)", "Dr (m)", "Dl (m)", "max e_d", "final", "th (deg)"],
                           ref, "Published figures (reference_results.csv)")
    return text, raw


LOO_METHODS = {"fusionkit graph (long horizon)": lambda s: graph_calibration(s, LONG_HORIZON)[0],
               "fusionkit graph (increments)": lambda s: graph_calibration(s, INCREMENTS)[0],
               "least squares": least_squares, "OptiOdom objective (ours)": checkpoint_fit, "UMBmark": umbmark_parameters}

# The graph's wheel objectives, each left one run out: the documented one (LONG_HORIZON) and what it differs from.
OBJECTIVES = {
    "increments: wheels.preintegrated between states 1 s apart": INCREMENTS,
    "long horizon from each run's start only (anchors: recording_start)": {
        **LONG_HORIZON, "anchors": "recording_start", "mocap_scale": None},
    "long horizon, every checkpoint, windows up to 20 s": {**LONG_HORIZON, "horizon": 20.0, "mocap_scale": None},
    "long horizon, every checkpoint, whole runs": {**LONG_HORIZON, "mocap_scale": None},
    "long horizon, every checkpoint, whole runs, motion capture noise_scale: estimate (documented)": LONG_HORIZON,
    "increments + the documented long horizon": {**LONG_HORIZON, "objective": "increments+long_horizon",
                                               "wheel_sigma": INCREMENTS["wheel_sigma"]},
}


def graph_held_out(session, settings: dict) -> dict:
    """The graph calibration with `settings` left one run out (held_out): the largest held-out max e_d and final
    error, and the range of chi2/dof over the five-run fits."""
    chi2 = []

    def fit(runs):
        params, _, result = graph_calibration(runs, settings)
        chi2.append(result.solution.chi2_per_dof)
        return params
    along, final = held_out(session, fit)
    return {"held_out_max_e_d": along, "held_out_max_final": final, "chi2_per_dof": (min(chi2), max(chi2))}


def leave_one_run_out(sessions) -> tuple[str, dict]:
    """Per session: each run dead-reckoned with the parameters calibrated on the other runs; the measures
    over those held-out runs (max e_d along any path, largest final error) beside the in-sample ones. UMBmark
    needs squares driven both ways: squares only."""
    rows, raw = [], {}
    for name, session in sessions.items():
        for label, fit in LOO_METHODS.items():
            if label == "UMBmark" and name != SQUARE:
                continue
            along, final = held_out(session, fit)
            inside = evaluate(session, fit(session))
            raw[f"{label}, {SHORT[name]}"] = {"held_out_max_e_d": along, "held_out_max_final": final,
                                               "in_sample_max_e_d": inside.max_along,
                                               "in_sample_max_final": inside.max_final}
            rows.append([f"{label}, {SHORT[name]}", f"{along:.4f}", f"{final:.4f}",
                         f"{inside.max_along:.4f}", f"{inside.max_final:.4f}"])
    for r in published():
        rows.append([f"{r['method']} published, {r['experiment']}", "-", "-", f"{float(r['max_ed_m']):.4f}",
                     f"{float(r['max_final_ed_m']):.4f}"])
    text = table(["calibration, session", "held out: max e_d", "max final", "in-sample: max e_d", "max final"],
                 rows, "Leave one run out: each run with the parameters of the session's other runs (m)")
    return text, raw


def objectives(sessions) -> tuple[str, dict]:
    """The graph's wheel objectives left one run out (max e_d along any held-out path, largest final error, and
    the chi2/dof range of the five-run fits), beside OptiOdom's objective reimplemented."""
    rows, raw = [], {}
    for label, settings in OBJECTIVES.items():
        cells = []
        for name, session in sessions.items():
            out = raw[(label, SHORT[name])] = graph_held_out(session, settings)
            chi2 = out["chi2_per_dof"]
            cells += [f"{out['held_out_max_e_d']:.4f}", f"{out['held_out_max_final']:.4f}",
                      f"{chi2[0]:.2g}-{chi2[1]:.2g}"]
        rows.append([label, *cells])
    cells = []
    for name, session in sessions.items():
        along, final = held_out(session, checkpoint_fit)
        raw[("OptiOdom objective (ours)", SHORT[name])] = {"held_out_max_e_d": along, "held_out_max_final": final}
        cells += [f"{along:.4f}", f"{final:.4f}", "-"]
    rows.append(["OptiOdom objective (ours): scipy, checkpoints from each run's true start", *cells])
    head = ["wheel objective", "circ held out max e_d", "max final", "chi2/dof", "squares held out max e_d",
            "max final", "chi2/dof"]
    return table(head, rows, "fusionkit graph, leave one run out: its wheel objectives (m)"), raw


def segment_lengths(sessions) -> tuple[str, dict]:
    """The least-squares fit with each run cut into segments of 1, 5 and 20 s instead of whole runs."""
    rows, raw = [], {}
    for cycles in (None, 400, 100, 20):
        label = "whole runs" if cycles is None else f"{cycles / 20:g} s"
        for on in (CIRCULAR, SQUARE):
            params = least_squares(sessions[on], cycles)
            rows.append([f"{label}, {SHORT[on]}", *_cells(sessions, params, on)])
            raw[(label, SHORT[on])] = params
    head = ["segments, calibrated on", "circ max e_d", "final", "th (deg)", "squares max e_d", "final", "th (deg)"]
    return table(head, rows, "Least squares: sensitivity to the segment length"), raw


def graph_settings(sessions, quick: bool) -> tuple[str, dict]:
    """The graph calibration with the wheel noise and the state spacing off their a-priori values."""
    rows, raw = [], {}
    sigmas, spacings = ((0.0001, 0.01), (5, 100)) if quick else ((0.0001, 0.0003, 0.003, 0.01), (5, 10, 50, 100))
    variants = [("wheel_sigma", v) for v in sigmas] + [("state_every", v) for v in spacings]
    for key, value in [(None, None)] + variants:
        settings = INCREMENTS if key is None else {**INCREMENTS, key: value}
        label = "a priori" if key is None else f"{key} {value:g}"
        for on in (CIRCULAR, SQUARE):
            params, _, result = graph_calibration(sessions[on], settings)
            rows.append([f"{label}, {SHORT[on]}", f"{result.solution.chi2_per_dof:.3g}",
                         *_cells(sessions, params, on)])
            raw[(label, SHORT[on])] = params
    head = ["settings, calibrated on", "chi2/dof", "circ max e_d", "final", "th (deg)", "squares max e_d", "final",
            "th (deg)"]
    title = (f"fusionkit graph (increments): sensitivity to its settings (a priori: wheel_sigma "
             f"{INCREMENTS['wheel_sigma']} m/sqrt(s), a state every {INCREMENTS['state_every']} cycles)")
    return table(head, rows, title), raw


def graph_noise_held_out(sessions, quick: bool) -> tuple[str, dict]:
    """The graph's leave-one-run-out errors with its wheel noise at the a-priori 1 mm/sqrt(s) and lower, and
    with both entries' noise scales estimated from the five runs (variance components), beside the chi2/dof
    of the fits on five runs: how much a noise stated as the data show (chi2/dof near 1) changes the held-out
    errors."""
    rows, raw = [], {}
    variants = [(f"{sigma:g}", {**INCREMENTS, "wheel_sigma": sigma})
                for sigma in (INCREMENTS["wheel_sigma"],) + (() if quick else (0.0003,)) + (0.0001,)]
    variants.append((f"{INCREMENTS['wheel_sigma']:g}, both entries' noise_scale: estimate",
                     {**INCREMENTS, "noise_scales": True}))
    for label, settings in variants:
        cells = []
        for name, session in sessions.items():
            out = raw[(label, SHORT[name])] = graph_held_out(session, settings)
            chi2 = out["chi2_per_dof"]
            cells += [f"{chi2[0]:.2f}-{chi2[1]:.2f}", f"{out['held_out_max_e_d']:.4f}", f"{out['held_out_max_final']:.4f}"]
        rows.append([label, *cells])
    head = ["wheel_sigma (m/sqrt(s))", "circ chi2/dof", "held out max e_d", "max final", "squares chi2/dof",
            "held out max e_d", "max final"]
    text = table(head, rows, "fusionkit graph (increments), leave one run out: its wheel noise as stated a priori "
                             "and lower")
    for name, session in sessions.items():  # the scales the data give on all six runs
        scales = graph_calibration(session, variants[-1][1])[2].solution.noise_scales
        raw[("noise_scales", SHORT[name])] = scales
        text += f"\nnoise scales estimated on all {SHORT[name]} runs: " + ", ".join(
            f"{label.split(':')[1]} {fit['scale']:.3f} +- {fit['sigma']:.3f} (redundancy {fit['redundancy']:.0f}, "
            f"{fit['rounds']} rounds)" for label, fit in scales.items())
    return text, raw


def run(quick: bool) -> dict:
    if not DATA.is_dir():
        return {"text": f"(OptiOdom recordings not found at {DATA}: skipped)", "raw": {}}
    sessions = {name: load_session(name) for name in (CIRCULAR, SQUARE)}
    return run_parts({"calibrations": lambda: calibrations(sessions),
                      "leave_one_run_out": lambda: leave_one_run_out(sessions),
                      "objectives": lambda: objectives(sessions),
                      "segments": lambda: segment_lengths(sessions),
                      "graph_settings": lambda: graph_settings(sessions, quick),
                      "graph_noise_held_out": lambda: graph_noise_held_out(sessions, quick)})


def summary(results: dict) -> list[str]:
    if not results["raw"]:
        return ["wheels (real): OptiOdom recordings not found, skipped"]
    c = results["raw"]["calibrations"]
    nom, gsq, gci = (c["nominal"], c["fusionkit graph (long horizon), squares"],
                     c["fusionkit graph (long horizon), circular"])
    circ = {k: (v["circular"].max_along, v["circular"].max_final) for k, v in
            (("nominal", nom), ("in", gci), ("held", gsq))}
    return ["wheels (real, OptiOdom): circular runs max e_d / max final error: nominal %.4f / %.4f m, fusionkit graph (long horizon) "
            "calibrated on them %.4f / %.4f m (published OptiOdom 0.0293 / 0.0285 m), on the squares (held out) "
            "%.4f / %.4f m" % (*circ["nominal"], *circ["in"], *circ["held"])]


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
