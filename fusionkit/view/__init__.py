"""`fusionkit view`: the 3-D scene of a run (scene.json, written by `fusionkit run`) in an open3d window or
rendered to a PNG; matplotlib draws it when open3d or an OpenGL context is missing."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from .render_matplotlib import render_png as matplotlib_png
from .scene import SCENE_FILE, is_empty, load_scene

RENDERER = Path(__file__).with_name("render_open3d.py")
OPEN3D_TIMEOUT = 120  # s: a software-rendered scene takes well under one


def _open3d(mode: str, folder: Path, *args: str) -> tuple[bool, str]:
    """Runs render_open3d.py in its own process: (succeeded, why not in one line)."""
    if importlib.util.find_spec("open3d") is None:
        return False, "open3d is not installed (pip install 'fusionkit[view]')"
    try:
        proc = subprocess.run([sys.executable, str(RENDERER), mode, str(folder / SCENE_FILE), *args],
                              capture_output=True, text=True, timeout=OPEN3D_TIMEOUT)
    except subprocess.TimeoutExpired:
        return False, f"open3d did not finish within {OPEN3D_TIMEOUT} s"
    if proc.returncode == 0:
        return True, ""
    last = (proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"])[-1]
    return False, f"open3d could not render ({last[:160]})"


def drawable_scene(folder: Path) -> dict:
    """The output folder's scene; ValueError when it has nothing to draw."""
    scene = load_scene(folder)
    if is_empty(scene):
        raise ValueError(f"{folder}: the run has nothing to draw in 3-D (no trajectory, point parameter or robot "
                         "geometry)")
    return scene


def render_png(folder: Path, file: Path, time: float | None = None, backend: str = "auto") -> str:
    """Renders the scene of output folder `folder` into the new file `file`, written whole or not at all and
    never over an existing file (ValueError); returns a one-line note when matplotlib drew it instead of
    open3d, else ''."""
    if file.exists():
        raise ValueError(f"{file}: exists; fusionkit writes only new files (choose another name)")
    if not file.parent.is_dir():
        raise ValueError(f"{file}: folder {file.parent} does not exist")
    scene = drawable_scene(folder)
    with tempfile.TemporaryDirectory(dir=file.parent) as tmp:
        part = Path(tmp) / file.name
        note = ""
        done = False
        if backend != "matplotlib":
            done, why = _open3d("png", folder, str(part), "" if time is None else str(time))
            note = f"{why}: drawn with matplotlib" if not done else ""
        if not done:
            matplotlib_png(scene, part, time)
        try:
            os.link(part, file)  # the finished image appears at once, and only where no file is
        except FileExistsError:
            raise ValueError(f"{file}: exists; fusionkit writes only new files (choose another name)") from None
    return note


def open_window(folder: Path, time: float | None = None) -> str:
    """An interactive open3d window on the scene; without open3d or a display, matplotlib's window.
    Returns a one-line note about the fallback ('' when open3d showed it)."""
    scene = drawable_scene(folder)
    done, why = _open3d("window", folder, "" if time is None else str(time))
    if done:
        return ""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise RuntimeError(f"{why}, and there is no display for matplotlib's window: use --png FILE")
    import matplotlib.pyplot as plt
    from .render_matplotlib import draw_scene
    draw_scene(scene, time)
    plt.show()
    return f"{why}: shown with matplotlib"
