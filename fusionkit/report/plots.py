"""plots/trajectory.png (estimate vs truth, top view and height) and plots/residuals.png
(whitened residual norm per factor entry: ~1 means the sigmas fit the data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..pipeline import RunResult


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
            top.plot(q[:, 0], q[:, 1], "--", color=line.get_color(), alpha=0.6, label=f"{robot} truth")
            height.plot(ref.t, q[:, 2], "--", color=line.get_color(), alpha=0.6)
    top.set(xlabel="x [m]", ylabel="y [m]", title="trajectory (top view)", aspect="equal")
    height.set(xlabel="t [s]", ylabel="z [m]", title="height")
    top.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(file, dpi=110)
    plt.close(fig)


def plot_residuals(result: RunResult, file: Path) -> None:
    plt = _pyplot()
    groups: dict[str, list[float]] = {}
    values = result.solution.values
    for r in result.problem.records:
        groups.setdefault(r.label, []).append(float(np.sqrt(2.0 * r.factor.error(values) / max(r.factor.dim(), 1))))
    fig, ax = plt.subplots(figsize=(10, 1.2 + 0.5 * len(groups)))
    labels = list(groups)
    ax.boxplot([groups[k] for k in labels], orientation="horizontal", showfliers=True)
    ax.set_yticks(range(1, len(labels) + 1), labels, fontsize=8)
    ax.axvline(1.0, color="gray", linestyle=":")
    ax.set(xlabel="whitened residual RMS per factor (1 = as expected from the sigmas)", title="residuals")
    fig.tight_layout()
    fig.savefig(file, dpi=110)
    plt.close(fig)


def write_plots(result: RunResult, folder: Path) -> None:
    if result.trajectories:
        plot_trajectories(result, folder / "trajectory.png")
    plot_residuals(result, folder / "residuals.png")
    for name, draw in result.problem.plots.items():
        draw(folder / f"{name}.png")
