"""A scene (scene.json) drawn with matplotlib's 3-D axes into a PNG: the fallback when open3d or an
OpenGL context is missing, and the render embedded in report.html."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _ellipsoid_wire(ax, shape: dict) -> None:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)  # (9, 16, 3)
    p = unit @ np.asarray(shape["axes"]).T + np.asarray(shape["center"])
    ax.plot_wireframe(p[..., 0], p[..., 1], p[..., 2], color=shape["color"], linewidth=0.3, alpha=0.5)


def _draw(ax, shape: dict, labelled: set) -> np.ndarray:
    """Draws one shape; returns its points (for the axes' limits)."""
    quiet = "3-sigma" in shape["label"] or " body " in shape["label"]
    label = shape["label"] if shape["label"] not in labelled and not quiet else None
    labelled.add(shape["label"])
    if shape["kind"] == "points":
        p = np.asarray(shape["xyz"]).reshape(-1, 3)
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], color=shape["color"], s=shape["size"] ** 2 / 2, label=label,
                   depthshade=False)
        return p
    if shape["kind"] == "lines":
        seg = np.asarray(shape["segments"]).reshape(-1, 2, 3)
        if len(seg) == 0:
            return np.zeros((0, 3))
        # one polyline with NaN breaks: one artist however many segments
        path = np.concatenate([seg, np.full((len(seg), 1, 3), np.nan)], axis=1).reshape(-1, 3)
        ax.plot(path[:, 0], path[:, 1], path[:, 2], color=shape["color"], linewidth=shape["width"], label=label)
        return seg.reshape(-1, 3)
    _ellipsoid_wire(ax, shape)
    return np.asarray(shape["center"])[None]


def frame_index(scene: dict, time: float | None) -> int | None:
    """The frame nearest to `time` (s); the last frame when None; None without frames."""
    times = scene["times"]
    if not times:
        return None
    return len(times) - 1 if time is None else int(np.argmin(np.abs(np.asarray(times) - time)))


def render_png(scene: dict, file: Path, time: float | None = None, size: tuple[int, int] = (900, 700)) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = draw_scene(scene, time, size)
    fig.savefig(file, dpi=100)
    plt.close(fig)


def draw_scene(scene: dict, time: float | None = None, size: tuple[int, int] = (900, 700)):
    """The scene at the frame nearest to `time` in a new pyplot figure (returned)."""
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    k = frame_index(scene, time)
    shapes = scene["trajectories"] + scene["static"] + (scene["frames"][k] if k is not None else [])
    labelled: set = set()
    points = [_draw(ax, s, labelled) for s in shapes]
    every = np.concatenate([p for p in points if len(p)]) if any(len(p) for p in points) else np.zeros((1, 3))
    every = every[np.isfinite(every).all(axis=1)]
    lo, hi = every.min(axis=0), every.max(axis=0)
    half = max(float((hi - lo).max()) / 2, 1e-3)
    mid = (lo + hi) / 2
    ax.set(xlim=(mid[0] - half, mid[0] + half), ylim=(mid[1] - half, mid[1] + half),
           zlim=(mid[2] - half, mid[2] + half), xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
    when = f" at t = {scene['times'][k]:.2f} s" if k is not None else ""
    ax.set_title(f"{scene['name']}{when} (ellipsoids: 3 sigma)", fontsize=10)
    if labelled - {s["label"] for s in shapes if "3-sigma" in s["label"]}:
        ax.legend(fontsize=7, loc="upper left")
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=0.95)
    return fig
