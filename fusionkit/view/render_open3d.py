"""A scene (scene.json) drawn with open3d: `png` offscreen into a file, `window` interactive (the arrow keys
step through the frames' times, space plays them).

Run as its own process (`python render_open3d.py png|window SCENE.json [PNG] [TIME]`): an OpenGL context
that cannot be made ends open3d's process with a crash rather than an exception (measured with
open3d 0.19-0.20 without a display: segfaults, aborts and hangs), so fusionkit calls this file in a
subprocess and falls back to matplotlib. Uses the legacy Visualizer, which renders offscreen through EGL
(Mesa's software renderer included) when there is no display. Imports only numpy and open3d.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import open3d as o3d


def _rgb(color: str) -> list[float]:
    return [int(color[i:i + 2], 16) / 255 for i in (1, 3, 5)]


def _geometry(shape: dict) -> list:
    if shape["kind"] == "points":
        out = []
        for p in np.asarray(shape["xyz"]).reshape(-1, 3):
            ball = o3d.geometry.TriangleMesh.create_sphere(radius=0.004 * shape["size"])
            ball.translate(p)
            ball.paint_uniform_color(_rgb(shape["color"]))
            ball.compute_vertex_normals()
            out.append(ball)
        return out
    if shape["kind"] == "lines":
        seg = np.asarray(shape["segments"]).reshape(-1, 2, 3)
        if len(seg) == 0:
            return []
        lines = o3d.geometry.LineSet(o3d.utility.Vector3dVector(seg.reshape(-1, 3)),
                                     o3d.utility.Vector2iVector(np.arange(2 * len(seg)).reshape(-1, 2)))
        lines.paint_uniform_color(_rgb(shape["color"]))
        return [lines]
    sphere = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=12)
    vertices = np.asarray(sphere.vertices) @ np.asarray(shape["axes"]).T + shape["center"]
    sphere.vertices = o3d.utility.Vector3dVector(vertices)
    wire = o3d.geometry.LineSet.create_from_triangle_mesh(sphere)
    wire.paint_uniform_color(_rgb(shape["color"]))
    return [wire]


def _frame_shapes(scene: dict, k: int | None) -> list:
    shapes = scene["trajectories"] + scene["static"] + (scene["frames"][k] if k is not None else [])
    return [g for s in shapes for g in _geometry(s)]


def _nearest(scene: dict, time: float | None) -> int | None:
    if not scene["times"]:
        return None
    return len(scene["times"]) - 1 if time is None else int(np.argmin(np.abs(np.asarray(scene["times"]) - time)))


def _oblique(vis) -> None:
    """Look down at the scene from the front left, z up (open3d's default looks along -z)."""
    view = vis.get_view_control()
    view.set_front([-0.45, -0.75, 0.5])
    view.set_up([0.0, 0.0, 1.0])
    view.set_zoom(0.75)


def png(scene: dict, file: str, time: float | None, size=(900, 700)) -> int:
    vis = o3d.visualization.Visualizer()
    if not vis.create_window(visible=False, width=size[0], height=size[1]):
        print("open3d: no OpenGL context", file=sys.stderr)
        return 3
    for g in _frame_shapes(scene, _nearest(scene, time)):
        vis.add_geometry(g)
    vis.get_render_option().background_color = np.ones(3)
    _oblique(vis)
    vis.poll_events()
    vis.update_renderer()
    image = np.asarray(vis.capture_screen_float_buffer(do_render=True))
    vis.destroy_window()
    if image.size == 0 or float(image.std()) < 1e-3:
        print("open3d: blank image", file=sys.stderr)
        return 4
    o3d.io.write_image(file, o3d.geometry.Image((255 * image).astype(np.uint8)))
    return 0


def window(scene: dict, time: float | None) -> int:
    vis = o3d.visualization.VisualizerWithKeyCallback()
    if not vis.create_window(window_name=f"fusionkit: {scene['name']}", width=1200, height=900):
        print("open3d: no window (no display?)", file=sys.stderr)
        return 3
    state = {"k": _nearest(scene, time), "dynamic": []}
    for g in _frame_shapes(scene, None):
        vis.add_geometry(g)

    def show(k):
        for g in state["dynamic"]:
            vis.remove_geometry(g, reset_bounding_box=False)
        state["dynamic"] = [g for s in (scene["frames"][k] if k is not None else []) for g in _geometry(s)]
        for g in state["dynamic"]:
            vis.add_geometry(g, reset_bounding_box=False)
        if k is not None:
            print(f"t = {scene['times'][k]:.2f} s", flush=True)
        return True

    def step(delta):
        def callback(_vis):
            if state["k"] is None:
                return False
            state["k"] = (state["k"] + delta) % len(scene["times"])
            return show(state["k"])
        return callback

    show(state["k"])
    _oblique(vis)
    vis.register_key_callback(262, step(1))   # right arrow
    vis.register_key_callback(263, step(-1))  # left arrow
    vis.register_animation_callback(None)
    playing = {"on": False}

    def toggle(_vis):
        playing["on"] = not playing["on"]
        vis.register_animation_callback(step(1) if playing["on"] else None)
        return False
    vis.register_key_callback(32, toggle)     # space
    vis.run()
    vis.destroy_window()
    return 0


def main(argv: list[str]) -> int:
    mode, scene_file = argv[0], argv[1]
    scene = json.loads(open(scene_file).read())
    if mode == "png":
        return png(scene, argv[2], float(argv[3]) if len(argv) > 3 and argv[3] != "" else None)
    return window(scene, float(argv[2]) if len(argv) > 2 and argv[2] != "" else None)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
