"""Time offsets estimated in the graph (docs/models/unified_graph.md#time-offsets), shared by
benchmarks/bench_time_offset.py: a cable robot whose winch encoders lag the motion capture, and a UWB robot
whose ranges lag its wheel odometry.

Cable (`cable.cdpr`, ARAS-CAM, dynamic motion: the end-effector swings): encoders and force sensors at
40 Hz lagging by LAG (their sample stamped t reads the robot at t - 0.030 s on the motion-capture clock),
motion capture at 4 Hz. The graph is calibrated on the first half of the recording: one state per encoder
sample (on the encoders' clock), `pose.absolute` on the motion capture with `time_offset:` (the mocap
sample stamped t was taken at t + 0.030 s on the encoders' clock: the offset sits on the sparser stream),
`cable.elastic_length`, a loose `motion.constant_velocity` prior between the states (1 m/s and 1 rad/s
per sqrt(s); the commanded accelerations reach 5 m/s^2). The held-out check predicts, on the second half,
each encoder reading at each motion-capture frame from the tracked pose and the calibration:
z_i = (1 - T_i/EA) ||R b_i + p - a_i|| + l0_i, the encoders (and tensions) interpolated at the frame's
time on their clock, t + offset. Its noise floor is the same prediction with the true calibration and
offset (encoder, tension and tracking noise, interpolation between encoder samples).

UWB (`uwb.sim`, 60 s at 10 Hz, 4 anchors, drifting biases): ranges lagging by 50 ms; the position error
against the truth with the offset estimated (`uwb_time_offset`) and without.

IMU against motion capture (`uwb.drone`, 30 s): states at the 10 Hz ranging epochs on the IMU's clock
(200 Hz, preintegrated between them), motion capture at 50 Hz lagging by 20 ms, its offset first guessed
from its turn rate against the gyro's, then estimated with the states' IMU velocities in the interpolation
or without them (Catmull-Rom tangents from the neighbouring poses).
"""

from __future__ import annotations

import copy

import numpy as np

from fusionkit.api import robot_description_data, nearest
from fusionkit.pipeline import estimate
from fusionkit.plugins import registry
from fusionkit.simulate import simulated_config

LAG = 0.030  # s: the encoders read the robot this long before their stamp
CABLE = {"robot": "arascam", "motion": "dynamic", "rate": 40.0, "mocap_every": 10, "duration": 25.0,
         "time_offset": {"lengths": -LAG, "tensions": -LAG}}
MOCAP_OFFSET = "mocap_time_offset"
MOCAP_SIGMA = {"rotation": 0.002, "translation": 0.001}
ENCODER_SIGMA, TENSION_SIGMA = 0.001, 0.1
MOTION_SIGMA = {"rotation": 1.0, "translation": 1.0}
UWB_LAG = 0.050
UWB = {"duration": 60.0, "time_offset": {"ranges": -UWB_LAG}}
DRONE_LAG = 0.020
DRONE = {"duration": 30.0, "mocap_rate": 50.0, "time_offset": {"mocap": -DRONE_LAG}}


def cable_config(config: dict, half: float, offset: bool, noise: dict[str, float] | None = None,
                 offset_on: str = "mocap") -> None:
    """Edit the simulator's config into the motion-capture + encoders calibration of the first `half` s.
    `offset_on`: the entry given the time offset, the 4 Hz motion capture ("mocap": states on the encoders'
    clock) or the 40 Hz encoders ("encoders": states at 40 Hz on the motion capture's clock); `noise`
    scales the estimator's sigmas {"encoder": x, "mocap": x} against the simulator's."""
    noise = noise or {}
    sim = registry().get("simulators", "cable.cdpr")()
    desc = copy.deepcopy(sim.robots(CABLE)["cdpr"])
    desc["parameters"].pop("encoder_time_offset", None)
    desc["parameters"][MOCAP_OFFSET] = {"type": "scalar", "value": 0.0, "sigma": 1.0, "unit": "s"}
    clock = "lengths" if offset_on == "mocap" else "mocap"
    config["robots"] = {"cdpr": {"description": desc,
                                 "states": {"stream": clock, "rate": CABLE["rate"], "end": half - 1e-6}}}
    mocap = {"type": "pose.absolute", "robot": "cdpr", "stream": "mocap",
             "sigma": {k: v * noise.get("mocap", 1.0) for k, v in MOCAP_SIGMA.items()}}
    lengths = {"type": "cable.elastic_length", "robot": "cdpr", "stream": "lengths", "tension_stream": "tensions",
               "sigma": ENCODER_SIGMA * noise.get("encoder", 1.0), "tension_sigma": TENSION_SIGMA}
    guess = []
    if offset:
        on, stream, reference = (mocap, "mocap", "lengths") if offset_on == "mocap" else (lengths, "lengths", "mocap")
        on["time_offset"] = {"parameter": MOCAP_OFFSET}
        guess = [{"type": "time.offset_guess", "robot": "cdpr", "parameter": MOCAP_OFFSET, "stream": stream,
                  "reference": reference}]
    config["factors"] = [mocap, {"type": "motion.constant_velocity", "robot": "cdpr", "sigma": MOTION_SIGMA}, lengths]
    config["initializers"] = guess + [{"type": "pose.interpolate", "robot": "cdpr", "stream": "mocap"},
                                      {"type": "cable.multilateration", "robot": "cdpr", "lengths": "lengths"}]
    config["solver"] = {"type": "batch", "method": "lm"}
    config["output"] = {"plots": False}
    config.pop("truth", None)


def predicted_rms(streams: dict, desc: dict, pulleys, offsets, delta: float, t_from: float) -> float:
    """RMS (m) over cables and motion-capture frames stamped after `t_from` of the encoder reading at the
    frame (interpolated at its time on the encoders' clock, stamp + delta) minus its prediction from the
    tracked pose and the calibration (pulleys a_i, encoder offsets l0_i; elastic cables)."""
    mocap, lengths, tensions = streams["mocap"], streams["lengths"], streams["tensions"]
    tau = mocap.t + delta
    use = (mocap.t >= t_from) & (tau >= lengths.t[0]) & (tau <= lengths.t[-1])
    poses = mocap.poses()
    b = np.asarray(desc["cables"]["attachments"], float)
    ea = desc["cables"]["stiffness_EA"]
    z = np.column_stack([np.interp(tau[use], lengths.t, c) for c in lengths.values.T])
    force = np.column_stack([np.interp(tau[use], tensions.t, c) for c in tensions.values.T])
    attach = np.array([[poses[k].transformFrom(bi) for bi in b] for k in np.flatnonzero(use)])
    reach = np.linalg.norm(attach - np.asarray(pulleys, float)[None], axis=2)
    predicted = (1 - force / ea) * reach + np.asarray(offsets, float)[None]
    return float(np.sqrt(np.mean((z - predicted) ** 2)))


def cable_case(seed: int, offset: bool = True, noise: dict[str, float] | None = None,
               offset_on: str = "mocap") -> dict:
    """Calibrate on the first half of one simulated recording; the offset's estimate, its error against the
    truth (the mocap stamp's offset on the encoders' clock is +LAG), the held-out rms and its floor."""
    half = 0.5 * CABLE["duration"]
    with simulated_config("cable.cdpr", CABLE, seed,
                          lambda c: cable_config(c, half, offset, noise, offset_on)) as config:
        result = estimate(config, keep_rejected=True)
    desc = robot_description_data(CABLE["robot"])
    cal, params = result.truth.calibration["cdpr"], result.parameters["cdpr"]
    out = {"estimate_s": result.timings["solve_s"], "iterations": result.solution.iterations,
           "chi2_per_dof": result.solution.chi2_per_dof,
           "floor_m": predicted_rms(result.streams, desc, cal["pulley"]["values"], cal["offset"]["values"], LAG, half)}
    delta = 0.0
    if offset:
        truth = LAG if offset_on == "mocap" else -LAG
        est = params[MOCAP_OFFSET]
        out.update(offset_s=est.values[0], sigma_s=float(est.sigma[0][0]), error_s=est.values[0] - truth)
        out["z"] = out["error_s"] / out["sigma_s"]
        delta = est.values[0] if offset_on == "mocap" else -est.values[0]
    out["heldout_m"] = predicted_rms(result.streams, desc, params["pulley"].values, params["offset"].values, delta,
                                     half)
    return out


def uwb_case(seed: int, offset: bool, duration: float = UWB["duration"], params: dict | None = None) -> dict:
    """Position RMSE (m) of robot a with the ranging lag estimated or ignored (`params`: the simulator's,
    default UWB); the offset's estimate."""
    def edit(config):
        config["output"] = {"plots": False}
        if not offset:
            for f in config["factors"]:
                f.pop("time_offset", None)
    with simulated_config("uwb.sim", {**(params or UWB), "duration": duration}, seed, edit) as config:
        result = estimate(config, keep_rejected=True)
    truth, est = result.truth.trajectories["a"], result.trajectories["a"]
    m = nearest(truth.t, est.t, 1e-6)
    err = est.pose_array()[m.row, :2] - truth.pose_array()[m.state, :2]
    out = {"position_m": float(np.sqrt(np.mean(np.sum(err ** 2, axis=1)))), "solve_s": result.timings["solve_s"],
           "iterations": result.solution.iterations}
    if offset:
        p = result.parameters["a"]["uwb_time_offset"]
        out.update(offset_s=p.values[0], sigma_s=float(p.sigma[0][0]), error_s=p.values[0] + UWB_LAG)
    return out


def drone_case(seed: int, velocities: bool, mocap_noise: float = 1.0) -> dict:
    """The mocap offset's guess, estimate, sigma and z-score (`mocap_noise`: the mocap sigma the estimator
    is told, times the simulator's); the solve time (s)."""
    def edit(config):
        config["output"] = {"plots": False}
        for f in config["factors"]:
            if "time_offset" in f:
                f["time_offset"]["velocities"] = velocities
                f["sigma"] = {k: v * mocap_noise for k, v in f["sigma"].items()}
    with simulated_config("uwb.drone", DRONE, seed, edit) as config:
        result = estimate(config)
    guess = next(d for label, d in result.problem.diagnostics.items() if "time.offset_guess" in label)
    p = result.parameters["drone"]["mocap_time_offset"]
    error, sigma = p.values[0] + DRONE_LAG, float(p.sigma[0][0])
    return {"guess_error_s": guess["offset_s"] + DRONE_LAG, "error_s": error, "sigma_s": sigma, "z": error / sigma,
            "solve_s": result.timings["solve_s"]}
