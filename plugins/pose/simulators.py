"""Synthetic pose datasets with truth: scaled monocular VO + sparse motion capture, and two
co-registered robots. Trajectories are vectorized with numpy; noise is drawn once per stream."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (POSE_NOISE_SCHEMA as SIGMA, Simulator, SourceOutput, noisy, odometry, pose_array_from,
                           pose_stream, poses_from_array, sample_times, smooth_trajectory)


class ScaledVoSimulator(Simulator):
    name = "pose.scaled_vo"
    summary = "3-D camera trajectory: monocular VO with unknown scale and drift + sparse motion capture"
    schema = {"type": "object",
              "properties": {"duration": {"type": "number", "exclusiveMinimum": 0},
                             "rate": {"type": "number", "exclusiveMinimum": 0},
                             "scale": {"type": "number", "exclusiveMinimum": 0},
                             "vo_sigma": SIGMA, "mocap_sigma": SIGMA,
                             "mocap_every": {"type": "integer", "minimum": 1},
                             "marker_offset": {"type": "array", "items": {"type": "number"},
                                               "minItems": 3, "maxItems": 3}},
              "additionalProperties": False}
    defaults = {"duration": 25.0, "rate": 30.0, "scale": 2.5, "mocap_every": 60, "marker_offset": [0.0, 0.0, 0.05],
                "vo_sigma": {"rotation": 0.002, "translation": 0.0016},
                "mocap_sigma": {"rotation": 0.01, "translation": 0.01}}

    def stream_columns(self, params: dict):
        from fusionkit.api import POSE_COLUMNS
        return {"vo": POSE_COLUMNS, "mocap": POSE_COLUMNS}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        t = sample_times(params["duration"], params["rate"])
        truth_arr = smooth_trajectory(t, np.array([1.5, 1.0, 0.4]), np.array([0.05, 0.1, 0.07]),
                                      np.array([0.0, 0.3, 1.0]), np.array([0.0, 0.0, 1.5]))
        truth = poses_from_array(truth_arr)
        vo = odometry(truth, params["vo_sigma"], rng, params["scale"])
        every = params["mocap_every"]
        rows = np.arange(0, len(t), every)
        marker = gtsam.Pose3(gtsam.Rot3(), np.asarray(params["marker_offset"], float))
        mocap = noisy([truth[i].compose(marker) for i in rows], params["mocap_sigma"], rng)
        return SourceOutput(
            {"vo": pose_stream("vo", t, vo, "simulated:vo"),
             "mocap": pose_stream("mocap", t[rows], mocap, "simulated:mocap")},
            {"cam": pose_stream("cam", t, truth_arr, "simulated:truth")},
            {"cam": {"vo_scale": {"type": "scalar", "value": float(params["scale"])}}})

    def robots(self, params: dict) -> dict[str, dict]:
        return {"cam": {
            "name": "handheld_camera", "model": "generic", "frames": ["world", "body"],
            "sensors": {"camera": {"type": "camera", "frame": "body"},
                        "marker": {"type": "mocap_marker", "frame": "body",
                                   "mount": {"translation": list(params["marker_offset"])}}},
            "parameters": {"vo_scale": {"type": "scalar", "value": 1.0, "sigma": 10.0}}}}

    def config(self, params: dict) -> dict:
        vo_sigma, mocap_sigma = _floored(params["vo_sigma"]), _floored(params["mocap_sigma"])
        return {
            "robots": {"cam": {"description": "robots/cam.yaml", "states": {"stream": "vo"}}},
            "factors": [
                {"type": "pose.scaled_relative", "robot": "cam", "stream": "vo", "scale": "vo_scale",
                 "sigma": vo_sigma},
                {"type": "pose.absolute", "robot": "cam", "stream": "mocap", "sensor": "marker",
                 "sigma": mocap_sigma}],
            "initializers": [
                {"type": "pose.scale_from_absolute", "robot": "cam", "stream": "vo", "anchor": "mocap",
                 "scale": "vo_scale"},
                {"type": "pose.dead_reckoning", "robot": "cam", "stream": "vo", "anchor": "mocap",
                 "scale": "vo_scale"}],
            "solver": {"type": "batch", "method": "lm"}}


class TwoRobotsSimulator(Simulator):
    name = "pose.two_robots"
    summary = "two robots with odometry, one with sparse motion capture, and robot-to-robot relative poses"
    schema = {"type": "object",
              "properties": {"duration": {"type": "number", "exclusiveMinimum": 0},
                             "rate": {"type": "number", "exclusiveMinimum": 0},
                             "odom_sigma": SIGMA, "relative_sigma": SIGMA, "mocap_sigma": SIGMA,
                             "relative_every": {"type": "integer", "minimum": 1},
                             "mocap_every": {"type": "integer", "minimum": 1}},
              "additionalProperties": False}
    defaults = {"duration": 30.0, "rate": 10.0, "relative_every": 5, "mocap_every": 25,
                "odom_sigma": {"rotation": 0.003, "translation": 0.01},
                "relative_sigma": {"rotation": 0.01, "translation": 0.02},
                "mocap_sigma": {"rotation": 0.01, "translation": 0.01}}

    def stream_columns(self, params: dict):
        from fusionkit.api import POSE_COLUMNS
        return {n: POSE_COLUMNS for n in ("a_odom", "b_odom", "a_mocap", "a_sees_b")}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        t = sample_times(params["duration"], params["rate"])
        a = poses_from_array(smooth_trajectory(t, np.array([3.0, 2.0, 0.2]), np.array([0.03, 0.06, 0.05]),
                                               np.zeros(3), np.array([0.0, 0.0, 0.5]), tilt=0.02))
        b_world = poses_from_array(smooth_trajectory(t, np.array([2.0, 2.5, 0.1]), np.array([0.04, 0.04, 0.05]),
                                                     np.array([0.0, 1.5, 0.0]), np.array([1.0, 0.5, 0.5]),
                                                     tilt=0.02))
        base_b = b_world[0]  # robot b's base frame is where it started
        b = [base_b.between(p) for p in b_world]
        rel_rows = np.arange(0, len(t), params["relative_every"])
        rel = noisy([a[i].between(b_world[i]) for i in rel_rows], params["relative_sigma"], rng)
        mocap_rows = np.arange(0, len(t), params["mocap_every"])
        mocap = noisy([a[i] for i in mocap_rows], params["mocap_sigma"], rng)
        streams = {
            "a_odom": pose_stream("a_odom", t, odometry(a, params["odom_sigma"], rng), "simulated:a_odom"),
            "b_odom": pose_stream("b_odom", t, odometry(b, params["odom_sigma"], rng), "simulated:b_odom"),
            "a_mocap": pose_stream("a_mocap", t[mocap_rows], mocap, "simulated:a_mocap"),
            "a_sees_b": pose_stream("a_sees_b", t[rel_rows], rel, "simulated:a_sees_b"),
        }
        truth = {"a": pose_stream("a", t, pose_array_from(a)), "b": pose_stream("b", t, pose_array_from(b))}
        calib = {"b": {"base_in_a": {"type": "pose3", "value": pose_array_from([base_b])[0].tolist()}}}
        return SourceOutput(streams, truth, calib)

    def robots(self, params: dict) -> dict[str, dict]:
        base = {"name": "mobile_base", "summary": "mobile base with wheel odometry and a motion-capture marker "
                "at the base origin", "model": "generic", "frames": ["world", "base"],
                "sensors": {"wheel_odometry": {"type": "odometry", "frame": "base"},
                            "marker": {"type": "mocap_marker", "frame": "base"}}}
        return {"a": base, "b": base}

    def config(self, params: dict) -> dict:
        """Both odometry chains, a's motion capture, b's base frame fixed at its start (pose.origin)
        and a's observations of b, which estimate b/base_in_a (configs/multirobot.yaml)."""
        return {
            "robots": {r: {"description": f"robots/{r}.yaml", "states": {"stream": f"{r}_odom"}} for r in "ab"},
            "factors": [
                *({"type": "pose.relative", "robot": r, "stream": f"{r}_odom", "sigma": _floored(params["odom_sigma"])}
                  for r in "ab"),
                {"type": "pose.absolute", "robot": "a", "stream": "a_mocap", "sensor": "marker",
                 "sigma": _floored(params["mocap_sigma"])},
                {"type": "pose.origin", "robot": "b", "sigma": {"rotation": 1e-4, "translation": 1e-4}},
                {"type": "pose.co_registration", "robot": "a", "other": "b", "stream": "a_sees_b",
                 "sigma": _floored(params["relative_sigma"])}],
            "initializers": [
                {"type": "pose.dead_reckoning", "robot": "a", "stream": "a_odom", "anchor": "a_mocap"},
                {"type": "pose.dead_reckoning", "robot": "b", "stream": "b_odom"},
                {"type": "pose.base_transform", "robot": "a", "other": "b", "stream": "a_sees_b"}],
            "solver": {"type": "batch", "method": "lm"}}


def _floored(sigma: dict) -> dict:
    """A simulated noise level as a factor sigma: at least 1e-4 (rad, m), so noise-free data stay solvable."""
    return {k: max(v, 1e-4) for k, v in sigma.items()}


SIMULATORS = [ScaledVoSimulator, TwoRobotsSimulator]
