"""plots/trajectory.png (estimate vs truth, top view and height), plots/error_vs_time_<robot>.png
(position error against truth per axis with the +-3 sigma band) and plots/residuals.png (whitened
residual norm per factor entry: ~1 means the sigmas fit the data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..eval.trajectory import matched_positions
from ..pipeline import RunResult

TRUTH_STYLE = {"color": "black", "linestyle": "--", "linewidth": 1.0}  # every estimate has a colour of its own


# fixed margins instead of tight_layout, which draws every figure twice (a third of the time of `fusionkit
# run` on small problems)
def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_trajectories(result: RunResult, file: Path) -> None:
    plt = _pyplot()
    fig, (top, height) = plt.subplots(1, 2, figsize=(12, 5))
    for robot, traj in result.trajectories.items():
        p = traj.pose_array()
        line, = top.plot(p[:, 0], p[:, 1], label=f"{robot} estimate")
        height.plot(traj.t, p[:, 2], color=line.get_color(), label=f"{robot} estimate")
        ref = result.truth.trajectories.get(robot)
        if ref is not None:
            q = ref.pose_array()
            top.plot(q[:, 0], q[:, 1], **TRUTH_STYLE, label=f"{robot} truth")
            height.plot(ref.t, q[:, 2], **TRUTH_STYLE, label=f"{robot} truth")
    top.set(xlabel="x [m]", ylabel="y [m]", title="trajectory (top view)", aspect="equal")
    height.set(xlabel="t [s]", ylabel="z [m]", title="height")
    top.legend(fontsize=8)
    height.legend(fontsize=8)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.1, top=0.93, wspace=0.25)
    fig.savefig(file, dpi=110)
    plt.close(fig)


def plot_errors(result: RunResult, robot: str, file: Path) -> None:
    """Estimate minus truth per world axis at the matched states (unaligned) with the +-3 sigma band."""
    m = matched_positions(result.trajectories[robot], result.truth.trajectories[robot],
                          result.position_sigma.get(robot))
    plt = _pyplot()
    fig, axes = plt.subplots(m.error.shape[1], 1, sharex=True, figsize=(10, 2.2 * m.error.shape[1] + 0.6))
    for i, (ax, name) in enumerate(zip(axes, "xyz")):
        if m.sigma is not None:
            ax.fill_between(m.t, -3 * m.sigma[:, i], 3 * m.sigma[:, i], color="C0", alpha=0.2, label="±3σ")
        ax.plot(m.t, m.error[:, i], color="C3", linewidth=1.0, label="estimate − truth")
        ax.axhline(0.0, color="gray", linewidth=0.5)
        ax.set_ylabel(f"{name} error [m]")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(f"{robot}: position error vs truth ({len(m.t)} of {len(result.trajectories[robot])} states "
                      "matched; no alignment)")
    axes[-1].set_xlabel("t [s]")
    height = fig.get_size_inches()[1]
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.55 / height, top=1 - 0.4 / height, hspace=0.12)
    fig.savefig(file, dpi=110)
    plt.close(fig)


def plot_residuals(result: RunResult, file: Path) -> None:
    plt = _pyplot()
    groups: dict[str, list[float]] = {}
    values = result.solution.values
    errors = result.problem.evaluator().record_errors(values)
    for r, error in zip(result.problem.records, errors):
        groups.setdefault(r.label, []).append(float(np.sqrt(2.0 * error / max(r.factor.dim(), 1))))
    fig, ax = plt.subplots(figsize=(10, 1.2 + 0.5 * len(groups)))
    labels = list(groups)
    ax.boxplot([groups[k] for k in labels], orientation="horizontal", showfliers=True)
    ax.set_yticks(range(1, len(labels) + 1), labels, fontsize=8)
    ax.axvline(1.0, color="gray", linestyle=":")
    ax.set(xlabel="whitened residual RMS per factor (1 = as expected from the sigmas)", title="residuals")
    height = fig.get_size_inches()[1]
    longest = max((len(k) for k in labels), default=10)  # 8-pt labels: about 0.065 inch per character
    fig.subplots_adjust(left=min(0.6, 0.03 + 0.0065 * longest), right=0.98, bottom=0.6 / height,
                        top=1 - 0.35 / height)
    fig.savefig(file, dpi=110)
    plt.close(fig)


def write_plots(result: RunResult, folder: Path) -> None:
    if result.trajectories:
        plot_trajectories(result, folder / "trajectory.png")
    for robot, ev in result.evaluation.get("trajectories", {}).items():
        if ev["matched_poses"]:
            plot_errors(result, robot, folder / f"error_vs_time_{robot}.png")
    plot_residuals(result, folder / "residuals.png")
    for name, draw in result.problem.plots.items():
        draw(folder / f"{name}.png")
