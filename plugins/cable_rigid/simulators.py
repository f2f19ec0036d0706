"""`cable.cdpr`: synthetic datasets of a suspended cable-driven parallel robot (docs/models/cable_rigid.md,
ARAS-CAM: 4 cables, monocular camera on the end-effector, 750 poses at 30 Hz).

The geometry comes from a shipped description (`robot`: a registered description's name). The TRUE pulleys are the
nominal ones perturbed by `pulley_error` per axis, then (`coplanar_pulleys`, default) projected
onto their best-fit plane: pulleys on one frame or ceiling, whose tilt is unknown; the encoders are relative and zeroed at the
home pose, so the true offsets make the noiseless readings 0 there (l0_i = -(1 - T_i/EA) l*_i at
home). The trajectory starts at rest at the home pose (x = y = 0, identity orientation), moves
along x, then y, then z (what the Monte-Carlo self-calibration needs: line -> shell, second axis
-> ring, third -> cluster), then a smooth mixed 3-D motion over the workspace with a few degrees
of roll/pitch/yaw.

`time_offset: {lengths: s, tensions: s}`: the encoder (force sensor) sample stamped t reads the robot
at t + offset on the motion-capture and VO clock (fusionkit's sign convention,
docs/models/unified_graph.md#time-offsets: encoders lagging by 30 ms is `lengths: -0.03`); with a `lengths` offset the description gains an
`encoder_time_offset` parameter (0 +- 1 s) and the config estimates it. A stream's clock may also run at a
wrong rate: `{lengths: {offset: s, rate: s/s}}` makes the sample stamped t read the robot at
t + offset + rate (t - t0) (t0: the first sample); a `lengths` rate adds an `encoder_clock_rate` parameter
(0 +- 0.01 s/s) that the config estimates too.

`motion: dynamic` (sequence 01): the commanded, quasi-static trajectory gives the cable lengths
the encoders read and the tensions; the true end-effector additionally swings like a damped
pendulum driven by the commanded accelerations (peak horizontal deviation `swing_amplitude`). With
4 cables for 6 degrees of freedom the swing keeps every cable length -- the end-effector sways
and tilts in the 2 free directions -- so the encoders cannot see it and forward kinematics (which
must assume the orientation) misses it, while the VO (worse by `dynamic_vo_factor`) sees it.

Streams: `vo` (scaled monocular VO, thesis eq. 4.3), `lengths` (l0..l{n-1}, thesis eqs. 4.1/4.2), `tensions`
(T0..T{n-1} in N, static equilibrium, quantized), `mocap` (noisy true poses, base frame).
Everything but the per-pose gtsam conversions and the tiny per-pose NNLS is vectorized.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fusionkit.api import (CLOCK_SCHEMA, ConfigError, GRAVITY, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS,
                           POSE_NOISE_SCHEMA as SIGMA, POSITIVE_SCHEMA as POSITIVE, Simulator, SourceOutput, Stream,
                           cable_pull_wrenches, clock_times, noisy, odometry, pose_stream, poses_from_array,
                           pulley_cables, robot_description_data, sample_times, weight_wrench)


ROBOT_NAME = "cdpr"  # robot name in the written config, truth and robots/cdpr.yaml
ENCODER_OFFSET = "encoder_time_offset"  # the description's parameter when the encoders are simulated lagging (s)
ENCODER_RATE = "encoder_clock_rate"  # ... and when their clock also runs at a wrong rate (s/s)


# Workspace and trajectory shape: amplitudes are fractions of the room from home to the pulley
# footprint's bounding box (x, y) and to the clearance below the pulleys / half the home height (z).
AXIS_FRACTION = 0.6      # single-axis segments
MIXED_FRACTION = 0.4     # mixed 3-D segment (ARAS-CAM: more and a cable goes slack in the low corners)
MAX_AMPLITUDE = 2.0      # m: large robots keep moderate speeds (lengthen `duration` to go slower)
MIN_CLEARANCE = 0.5      # attachments stay at least this far below the lowest pulley (m)
ORIENTATION_DEG = (2.0, 2.0, 4.0)  # roll, pitch, yaw amplitude in the mixed segment
SWIVEL_AXIS = np.array([0.0, 0.0, 1.0])  # simulated pulleys turn about the vertical; the cable arrives going up
REGION_MARGIN = 1.0      # m: the Monte-Carlo search region is the nominal pulleys' box grown by this
SCALE_RANGE = (0.2, 10.0)
# The zero pose defines the base frame (it is not measured): a looser prior adds its own
# uncertainty to every estimate (1 mrad there made the 1-sigma bounds hold 74 % instead of 68 %).
ORIGIN_SIGMA = 1e-6  # the VO scale is searched over this range (metres per VO unit)


@dataclass(frozen=True)
class Geometry:
    pulleys: np.ndarray            # (n, 3) a_i, base frame (with a pulley radius: the swivel points)
    attachments: np.ndarray        # (n, 3) b_i, end-effector frame
    stiffness_EA: float | None
    mass: float
    com: np.ndarray
    pulley_radius: float = 0.0     # m: swivelling pulleys (pulley.py); 0: fixed exit points

    @property
    def n(self) -> int:
        return len(self.attachments)


def nominal_geometry(desc: dict) -> Geometry:
    cables, ee = desc["cables"], desc.get("end_effector", {})
    return Geometry(np.asarray(desc["parameters"]["pulley"]["values"], float),
                    np.asarray(cables["attachments"], float), cables.get("stiffness_EA"),
                    float(ee.get("mass", 1.0)), np.asarray(ee.get("com", [0.0, 0.0, 0.0]), float))


def onto_best_fit_plane(points: np.ndarray) -> np.ndarray:
    """Points projected onto their least-squares plane."""
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre)[2][-1]
    return points - np.outer((points - centre) @ normal, normal)


# --------------------------------------------------------------------------------------- kinematics
def cables(pos: np.ndarray, rot: np.ndarray, geo: Geometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lengths l*_i (N, n) of thesis eq. 4.1, unit vectors u (N, n, 3) along each cable from its attachment
    towards the pulley, lever arms R b_i (N, n, 3)): to the exit point, or with geo.pulley_radius over a
    pulley swivelling about the vertical, along the free cable (pulley.py)."""
    arms = np.einsum("kij,cj->kci", rot, geo.attachments)
    points = pos[:, None, :] + arms
    if geo.pulley_radius > 0:
        over = [pulley_cables(points[:, i], np.broadcast_to(geo.pulleys[i], points[:, i].shape), geo.pulley_radius,
                              SWIVEL_AXIS) for i in range(geo.n)]
        return np.column_stack([length for length, _ in over]), -np.stack([n for _, n in over], axis=1), arms
    d = geo.pulleys[None] - points
    lengths = np.linalg.norm(d, axis=2)
    return lengths, d / lengths[..., None], arms


def cable_vectors(pos: np.ndarray, rot: np.ndarray, geo: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """(lengths l*_i (N, n), lever arms R b_i (N, n, 3)): `cables` without the directions."""
    lengths, _, arms = cables(pos, rot, geo)
    return lengths, arms


def wrench_matrix(pos: np.ndarray, rot: np.ndarray, geo: Geometry) -> np.ndarray:
    """(N, 6, n): column i is the wrench [u_i; R b_i x u_i] (about the end-effector origin, base
    frame) of a unit tension in cable i, u_i the unit vector from attachment towards the pulley."""
    _, u, arms = cables(pos, rot, geo)
    return cable_pull_wrenches(arms, u).transpose(0, 2, 1)


def gravity_wrench(rot: np.ndarray, geo: Geometry) -> np.ndarray:
    """(N, 6): weight m g at the centre of mass, about the end-effector origin, base frame."""
    return weight_wrench(rot, geo.com, geo.mass * GRAVITY)


def static_tensions(pos: np.ndarray, rot: np.ndarray, geo: Geometry) -> np.ndarray:
    """(N, n) non-negative tensions solving J^T T = -w_gravity in the least-squares sense."""
    from scipy.optimize import nnls
    A, w = wrench_matrix(pos, rot, geo), gravity_wrench(rot, geo)
    return np.array([nnls(Ak, -wk)[0] for Ak, wk in zip(A, w)])


def encoder_readings(lengths: np.ndarray, tensions: np.ndarray, offsets: np.ndarray,
                     stiffness_EA: float | None) -> np.ndarray:
    """Noiseless z_i = (1 - T_i/EA) l*_i + l0_i (thesis eq. 4.2), or l*_i + l0_i without stiffness (4.1)."""
    stretch = 0.0 if stiffness_EA is None else tensions / stiffness_EA
    return (1.0 - stretch) * lengths + offsets


# --------------------------------------------------------------------------------------- trajectory
def home_position(desc: dict) -> np.ndarray:
    """x = y = 0 at a height where the nominal cables are taut: if the description's nominal
    offsets are negative (relative encoders zeroed at home: l0 = -length at home), the height at
    which the mean nominal length equals -mean(offset); else half way up to the pulleys. Always at
    least MIN_CLEARANCE below the lowest pulley."""
    from scipy.optimize import brentq
    geo = nominal_geometry(desc)
    top = geo.pulleys[:, 2].min() - geo.attachments[:, 2].max() - MIN_CLEARANCE
    offsets = np.asarray(desc["parameters"]["offset"].get("values", [0.0]), float)

    def mean_length(z: float) -> float:
        return float(cable_vectors(np.array([[0.0, 0.0, z]]), np.eye(3)[None], geo)[0].mean())

    z = 0.5 * top
    if np.all(offsets < 0):
        target = -offsets.mean()
        low = top - 10 * target
        if (mean_length(top) - target) * (mean_length(low) - target) < 0:
            z = brentq(lambda zz: mean_length(zz) - target, low, top, xtol=1e-9)
    return np.array([0.0, 0.0, min(z, top)])


def _quintic(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk blend 0 -> 1 on s in [0, 1] (zero velocity and acceleration at both ends)."""
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def _waypoints(t: np.ndarray, times: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Piecewise minimum-jerk interpolation through `points` (m, d) at `times` (m,); held outside."""
    seg = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    s = _quintic((t - times[seg]) / (times[seg + 1] - times[seg]))
    return points[seg] + s[:, None] * (points[seg + 1] - points[seg])


def _window(s: np.ndarray, ramp: float = 0.15) -> np.ndarray:
    """Smooth 0 -> 1 -> 0 envelope on s in [0, 1] with minimum-jerk ramps of `ramp` at both ends."""
    return _quintic(s / ramp) * _quintic((1.0 - s) / ramp)


@dataclass(frozen=True)
class Plan:
    """The commanded trajectory: times, positions (N, 3), rotations (N, 3, 3), segment bounds."""

    t: np.ndarray
    pos: np.ndarray
    rot: np.ndarray
    segments: dict[str, tuple[float, float]]
    amplitude: dict[str, np.ndarray]


def workspace_extent(desc: dict, home: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Room from home to the pulley footprint (x, y) and to the clearance below the pulleys /
    half the home height (z): (room in the + direction, room in the - direction), each (3,)."""
    geo = nominal_geometry(desc)
    lo, hi = geo.pulleys[:, :2].min(axis=0), geo.pulleys[:, :2].max(axis=0)
    top = geo.pulleys[:, 2].min() - geo.attachments[:, 2].max() - MIN_CLEARANCE
    plus = np.array([hi[0] - home[0], hi[1] - home[1], top - home[2]])
    minus = np.array([home[0] - lo[0], home[1] - lo[1], 0.5 * home[2]])
    return plus, minus


def commanded_trajectory(t: np.ndarray, desc: dict, duration: float | None = None) -> Plan:
    """The plan at times `t` (s) of a sequence lasting `duration` (default: t's span plus one interval)."""
    from scipy.spatial.transform import Rotation
    home = home_position(desc)
    plus, minus = workspace_extent(desc, home)
    room = np.minimum(plus, minus)
    if duration is None:
        duration = float(t[-1]) + (t[1] - t[0] if len(t) > 1 else 0.0)
    rest = min(0.5, 0.02 * duration)
    axis_len = 0.18 * duration
    bounds, start = {}, rest
    for axis in "xyz":
        bounds[axis] = (start, start + axis_len)
        start += axis_len
    bounds["mixed"] = (start, duration)
    # single-axis segments: home -> +A -> -A -> home along one axis, minimum-jerk between waypoints
    axis_amp = np.minimum(AXIS_FRACTION * room, MAX_AMPLITUDE)
    times, points = [0.0, rest], [home, home]
    for i, axis in enumerate("xyz"):
        t0, t1 = bounds[axis]
        step = np.zeros(3)
        step[i] = axis_amp[i]
        for frac, p in ((0.25, home + step), (0.75, home - step), (1.0, home)):
            times.append(t0 + frac * (t1 - t0))
            points.append(p)
    pos = _waypoints(t, np.array(times), np.array(points))
    # mixed segment: windowed Lissajous figure over the workspace, a few degrees of rotation
    m0, m1 = bounds["mixed"]
    mixed_amp = np.minimum(MIXED_FRACTION * room, MAX_AMPLITUDE)
    tau = np.clip((t - m0) / (m1 - m0), 0.0, 1.0)
    env = _window(tau)[:, None]  # 0 before the segment (tau clipped to 0)
    cycles = np.array([2.0, 3.0, 2.5])
    phase = np.array([0.0, 0.5 * np.pi, 0.0])
    pos = pos + env * mixed_amp * np.sin(2 * np.pi * cycles * tau[:, None] + phase)
    ang = np.radians(ORIENTATION_DEG) * env * np.sin(2 * np.pi * np.array([1.5, 2.0, 1.0]) * tau[:, None]
                                                     + np.array([0.0, 1.0, 0.0]))
    rot = Rotation.from_euler("ZYX", ang[:, ::-1]).as_matrix()  # ang columns: roll, pitch, yaw
    return Plan(t, pos, rot, bounds, {"axis": axis_amp, "mixed": mixed_amp})


def pendulum_swing(t: np.ndarray, pos: np.ndarray, amplitude: float, frequency: float,
                   damping: float) -> np.ndarray:
    """(N, 2) horizontal deviation of a damped pendulum (natural `frequency` Hz, damping ratio
    `damping`) driven by the commanded horizontal acceleration, scaled to a peak of `amplitude`."""
    from scipy.signal import cont2discrete, lfilter  # lazy: scipy.signal takes ~1 s to import

    dt = float(t[1] - t[0])
    acc = np.gradient(np.gradient(pos[:, :2], dt, axis=0), dt, axis=0)
    w = 2 * np.pi * frequency
    num, den, _ = cont2discrete(([-1.0], [1.0, 2 * damping * w, w * w]), dt, method="bilinear")
    e = lfilter(np.ravel(num), den, acc, axis=0)
    peak = np.linalg.norm(e, axis=1).max()
    return e * (amplitude / peak) if peak > 0 else e


def length_jacobian(pos: np.ndarray, rot: np.ndarray, geo: Geometry) -> np.ndarray:
    """(N, n, 6) d l*_i / d [w, v]: a spatial twist about the end-effector origin (rotation w, rad;
    translation v, m; base frame) moves attachment i by v + w x R b_i."""
    _, u, arms = cables(pos, rot, geo)  # attachment -> pulley
    return -np.concatenate([np.cross(arms, u), u], axis=2)


def _moved(pos: np.ndarray, rot: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from scipy.spatial.transform import Rotation
    return pos + twist[:, 3:], Rotation.from_rotvec(twist[:, :3]).as_matrix() @ rot


def swing_at_constant_lengths(pos: np.ndarray, rot: np.ndarray, deviation: np.ndarray, geo: Geometry,
                              iterations: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Poses displaced by a horizontal `deviation` (N, 2) while every cable keeps its length: n < 6
    cables leave the end-effector 6 - n degrees of freedom (it swings, translating and tilting),
    which the encoders cannot see. The twist is the null-space motion of the cable Jacobian whose
    horizontal translation is `deviation` (least squares); Newton steps (minimum norm) then restore
    the lengths exactly (to 1e-12 m)."""
    target, _ = cable_vectors(pos, rot, geo)
    _, _, vt = np.linalg.svd(length_jacobian(pos, rot, geo))
    null = vt[:, geo.n:, :].transpose(0, 2, 1)  # (N, 6, 6 - n)
    coeff = np.einsum("kij,kj->ki", np.linalg.pinv(null[:, 3:5, :]), deviation)
    pos, rot = _moved(pos, rot, np.einsum("kij,kj->ki", null, coeff))
    for _ in range(iterations):
        lengths, _ = cable_vectors(pos, rot, geo)
        step = np.einsum("kij,kj->ki", np.linalg.pinv(length_jacobian(pos, rot, geo)), target - lengths)
        pos, rot = _moved(pos, rot, step)
    return pos, rot


# --------------------------------------------------------------------------------------- simulator
def _merged(defaults: dict, params: dict) -> dict:
    """Defaults under params, one level deep (so `--set vo_sigma.rotation=...` keeps translation)."""
    out = dict(defaults)
    for k, v in params.items():
        out[k] = {**defaults[k], **v} if isinstance(v, dict) and isinstance(defaults.get(k), dict) else v
    return out


def _scaled(sigma: dict, factor: float) -> dict:
    return {k: float(v) * factor for k, v in sigma.items()}


class CdprSimulator(Simulator):
    name = "cable.cdpr"
    summary = ("suspended CDPR (ARAS-CAM): scaled monocular VO, cable-length encoders, tensions and "
               "motion capture; smooth or dynamic (swinging) motion along x, y, z, then mixed")
    schema = {"type": "object",
              "properties": {"robot": {"enum": ["arascam", "cdpr_small"]},
                             "motion": {"enum": ["smooth", "dynamic"]},
                             "duration": POSITIVE, "rate": POSITIVE, "scale": POSITIVE,
                             "pulley_error": NONNEG, "coplanar_pulleys": {"type": "boolean"},
                             "pulley_radius": NONNEG,
                             "vo_sigma": SIGMA, "dynamic_vo_factor": {"type": "number", "minimum": 1},
                             "encoder_sigma": NONNEG, "tension_resolution": NONNEG, "tension_sigma": NONNEG,
                             "mocap_sigma": SIGMA, "mocap_every": {"type": "integer", "minimum": 1},
                             "swing_amplitude": NONNEG, "swing_frequency": POSITIVE,
                             "swing_damping": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1},
                             "time_offset": {"type": "object", "additionalProperties": False,
                                             "properties": {"lengths": CLOCK_SCHEMA, "tensions": CLOCK_SCHEMA}}},
              "additionalProperties": False}
    defaults = {"robot": "arascam", "motion": "smooth", "duration": 25.0, "rate": 30.0, "scale": 2.0,
                "pulley_error": 0.05, "coplanar_pulleys": True, "pulley_radius": 0.0,
                "vo_sigma": {"rotation": 0.001, "translation": 0.0005}, "dynamic_vo_factor": 2.5,
                "encoder_sigma": 0.001, "tension_resolution": 0.25, "tension_sigma": 0.1,
                "mocap_sigma": {"rotation": 0.002, "translation": 0.001}, "mocap_every": 1,
                "swing_amplitude": 0.02, "swing_frequency": 0.6, "swing_damping": 0.05, "time_offset": {}}

    def _params(self, params: dict) -> dict:
        return _merged(self.defaults, params)

    @staticmethod
    def _encoder_rate(params: dict) -> bool:
        """Whether the encoders' clock has a rate error (the description and config then gain ENCODER_RATE)."""
        raw = params["time_offset"].get("lengths")
        return isinstance(raw, dict) and "rate" in raw

    @staticmethod
    def _lagged(desc: dict, geo: Geometry, t: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
        """(lengths, tensions) of the commanded motion of the `duration`-s sequence at times `t`."""
        plan = commanded_trajectory(t, desc, duration)
        length, _ = cable_vectors(plan.pos, plan.rot, geo)
        return length, static_tensions(plan.pos, plan.rot, geo)

    def stream_columns(self, params: dict):
        n = len(robot_description_data(self._params(params)["robot"])["cables"]["attachments"])
        return {"vo": POSE_COLUMNS, "mocap": POSE_COLUMNS,
                "lengths": tuple(f"l{i}" for i in range(n)), "tensions": tuple(f"T{i}" for i in range(n))}

    @staticmethod
    def vo_sigma(params: dict) -> dict:
        """Per-frame VO noise: worse in dynamic motion by `dynamic_vo_factor`."""
        factor = params["dynamic_vo_factor"] if params["motion"] == "dynamic" else 1.0
        return _scaled(params["vo_sigma"], factor)

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        from scipy.spatial.transform import Rotation
        p = self._params(params)
        desc = robot_description_data(p["robot"])
        nominal = nominal_geometry(desc)
        t = sample_times(p["duration"], p["rate"])
        if len(t) < 10:
            raise ConfigError(f"<simulate {self.name}>: duration * rate gives {len(t)} sample(s); "
                              "expected at least 10")
        span = float(t[-1]) + (t[1] - t[0])  # the sequence's duration
        plan = commanded_trajectory(t, desc, span)
        true_pulleys = nominal.pulleys + rng.normal(0.0, p["pulley_error"], nominal.pulleys.shape)
        if p["coplanar_pulleys"]:
            true_pulleys = onto_best_fit_plane(true_pulleys)
        geo = Geometry(true_pulleys, nominal.attachments, nominal.stiffness_EA, nominal.mass, nominal.com,
                       p["pulley_radius"])

        # commanded (quasi-static) pose -> tensions and cable lengths the encoders read (stamped by their clock)
        tension = static_tensions(plan.pos, plan.rot, geo)
        length, _ = cable_vectors(plan.pos, plan.rot, geo)
        offsets = -encoder_readings(length[0], tension[0], np.zeros(geo.n), geo.stiffness_EA)
        lag = {name: self._lagged(desc, geo, clock_times(clock, t), span) for name, clock in p["time_offset"].items()}
        z = encoder_readings(*lag.get("lengths", (length, tension)), offsets, geo.stiffness_EA)
        z = z + rng.normal(0.0, p["encoder_sigma"], z.shape)
        tension = lag["tensions"][1] if "tensions" in lag else tension
        measured_t = tension + rng.normal(0.0, p["tension_sigma"], tension.shape)
        if p["tension_resolution"] > 0:
            measured_t = p["tension_resolution"] * np.round(measured_t / p["tension_resolution"])
        measured_t = np.maximum(measured_t, 0.0)

        # true pose: commanded (+ the pendulum swing the kinematics cannot see, dynamic motion)
        true_pos, true_rot = plan.pos, plan.rot
        if p["motion"] == "dynamic":
            swing = pendulum_swing(t, plan.pos, p["swing_amplitude"], p["swing_frequency"], p["swing_damping"])
            true_pos, true_rot = swing_at_constant_lengths(plan.pos, plan.rot, swing, geo)
        quat = Rotation.from_matrix(true_rot).as_quat()
        truth_arr = np.column_stack([true_pos, quat])
        truth = poses_from_array(truth_arr)
        vo = odometry(truth, self.vo_sigma(p), rng, p["scale"])
        rows = np.arange(0, len(t), p["mocap_every"])
        mocap = noisy([truth[i] for i in rows], p["mocap_sigma"], rng)

        n = geo.n
        streams = {
            "vo": pose_stream("vo", t, vo, "simulated:vo"),
            "lengths": Stream("lengths", t, tuple(f"l{i}" for i in range(n)), z, "simulated:lengths"),
            "tensions": Stream("tensions", t, tuple(f"T{i}" for i in range(n)), measured_t, "simulated:tensions"),
            "mocap": pose_stream("mocap", t[rows], mocap, "simulated:mocap"),
        }
        calibration = {ROBOT_NAME: {"pulley": {"type": "point3", "values": true_pulleys.tolist()},
                                    "offset": {"type": "scalar", "values": offsets.tolist()},
                                    "vo_scale": {"type": "scalar", "value": float(p["scale"])}}}
        encoders = p["time_offset"].get("lengths")
        if encoders is not None:
            offset = encoders["offset"] if isinstance(encoders, dict) else encoders
            calibration[ROBOT_NAME][ENCODER_OFFSET] = {"type": "scalar", "value": float(offset)}
        if self._encoder_rate(p):
            calibration[ROBOT_NAME][ENCODER_RATE] = {"type": "scalar", "value": float(encoders["rate"])}
        return SourceOutput(streams, {ROBOT_NAME: pose_stream(ROBOT_NAME, t, truth_arr, "simulated:truth")},
                            calibration)

    def robots(self, params: dict) -> dict[str, dict]:
        """The shipped description with its nominal values. Offsets: the nominal guess a user makes
        for encoders zeroed at home, -(nominal length at home), to the mm (for arascam that is the
        file's -2.9; cdpr_small's file has 0, absolute encoders, which this replaces). A camera and
        a `vo_scale` (1.0 +- 10, as in arascam) are added where the description has none."""
        p = self._params(params)
        desc = robot_description_data(p["robot"])
        geo = replace(nominal_geometry(desc), pulley_radius=p["pulley_radius"])
        if p["pulley_radius"] > 0:  # the written description models the pulleys (remove it to ignore them)
            desc["cables"].update(pulley_radius=p["pulley_radius"], swivel_axis=SWIVEL_AXIS.tolist())
        home = home_position(desc)
        length, _ = cable_vectors(home[None], np.eye(3)[None], geo)
        desc["parameters"]["offset"]["values"] = [round(-float(x), 3) for x in length[0]]
        # the camera rides on the end-effector; its VO scale is unknown (descriptions without one)
        desc.setdefault("sensors", {}).setdefault("camera", {"type": "monocular_camera", "frame": "end_effector"})
        desc["parameters"].setdefault("vo_scale", {"type": "scalar", "value": 1.0, "sigma": 10.0})
        if "lengths" in p["time_offset"]:
            desc["parameters"][ENCODER_OFFSET] = {"type": "scalar", "value": 0.0, "sigma": 1.0, "unit": "s"}
        if self._encoder_rate(p):
            desc["parameters"][ENCODER_RATE] = {"type": "scalar", "value": 0.0, "sigma": 0.01, "unit": "s/s"}
        return {ROBOT_NAME: desc}

    def _encoder_time_offset(self, params: dict) -> dict:
        """The cable.length entry's `time_offset:` when the encoders are simulated on their own clock."""
        if "lengths" not in params["time_offset"]:
            return {}
        rate = {"rate": ENCODER_RATE} if self._encoder_rate(params) else {}
        return {"time_offset": {"parameter": ENCODER_OFFSET, **rate}}

    def home_pose(self, params: dict) -> list[float]:
        """The true home pose [x, y, z, qx, qy, qz, qw]: the zero pose the user picks."""
        home = home_position(robot_description_data(self._params(params)["robot"]))
        return [float(x) for x in home] + [0.0, 0.0, 0.0, 1.0]

    def search_region(self, params: dict) -> dict:
        """Where the Monte-Carlo initializer looks for the pulleys: the nominal pulleys' bounding box
        grown by REGION_MARGIN on every side (a user knows the room, not the pulleys)."""
        pulleys = nominal_geometry(robot_description_data(self._params(params)["robot"])).pulleys
        return {"min": [round(float(x), 3) for x in pulleys.min(axis=0) - REGION_MARGIN],
                "max": [round(float(x), 3) for x in pulleys.max(axis=0) + REGION_MARGIN]}

    def initializers(self, params: dict) -> list[dict]:
        """Monte-Carlo self-calibration (pulleys, offsets and VO scale from the data alone, no
        prior values: the region is the room, the scale anywhere in SCALE_RANGE), then dead
        reckoning of the VO at the scale it found, from the home pose set by `pose.origin`; with lagging
        encoders, first the offset that best aligns the encoders' motion with the VO's (time.offset_guess)."""
        p = self._params(params)
        guess = [{"type": "time.offset_guess", "robot": ROBOT_NAME, "parameter": ENCODER_OFFSET, "stream": "lengths",
                  "reference": "vo"}] if "lengths" in p["time_offset"] else []
        return guess + [{"type": "cable.monte_carlo", "robot": ROBOT_NAME, "stream": "vo", "lengths": "lengths",
                 "region": self.search_region(p), "scale_range": list(SCALE_RANGE), "scale": "vo_scale",
                 "sigma": max(p["encoder_sigma"], 1e-4), "vo_sigma": self.vo_sigma(p)},
                {"type": "pose.dead_reckoning", "robot": ROBOT_NAME, "stream": "vo", "scale": "vo_scale"}]

    def config(self, params: dict) -> dict:
        """VO + encoders (no motion capture): origin prior at the home pose, scaled VO, rigid cable
        lengths; Monte-Carlo initialization and batch Levenberg-Marquardt."""
        p = self._params(params)
        vo_sigma = {k: max(v, 1e-4) for k, v in self.vo_sigma(p).items()}
        return {
            "robots": {ROBOT_NAME: {"description": f"robots/{ROBOT_NAME}.yaml", "states": {"stream": "vo"}}},
            "factors": [
                {"type": "pose.origin", "robot": ROBOT_NAME, "pose": self.home_pose(p),
                 "sigma": {"rotation": ORIGIN_SIGMA, "translation": ORIGIN_SIGMA}},
                {"type": "pose.scaled_relative", "robot": ROBOT_NAME, "stream": "vo", "scale": "vo_scale",
                 "sigma": vo_sigma},
                {"type": "cable.length", "robot": ROBOT_NAME, "stream": "lengths",
                 "sigma": max(p["encoder_sigma"], 1e-4),
                 **self._encoder_time_offset(p)}],
            "initializers": self.initializers(p),
            "solver": {"type": "batch", "method": "lm"}}


SIMULATORS = [CdprSimulator]
