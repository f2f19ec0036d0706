"""Initializers of the cable plugin: `cable.monte_carlo`, the Monte-Carlo self-calibration of the
pulleys, encoder offsets and VO scale (docs/models/cable_rigid.md#monte-carlo-initialization; the method is in
monte_carlo.py), and `cable.multilateration`, pulleys and offsets when the poses are known
(motion capture): `{type: cable.multilateration, robot: cdpr, lengths: lengths}`.

Config entry (initializers list, before `pose.dead_reckoning` with the same `scale`, so the poses
start at the scale found here; after the factors, so `pose.origin` has set the first pose):

    - type: cable.monte_carlo
      robot: cdpr
      stream: vo                       # unscaled VO poses
      lengths: lengths                 # encoder readings l0 .. l{n-1} (or `columns:`)
      region: {min: [-3, -2.5, 2], max: [3, 2.5, 4.5]}   # where pulleys may be (m, base frame)
      scale_range: [0.5, 5]            # where the VO scale may be (metres per VO unit)
      scale: vo_scale                  # the scalar parameter the VO factor uses
      sigma: 0.001                     # encoder noise (m)
      initial_length_spread: 0.05      # default: cable lengths at the first pose known within +-5 cm
      vo_sigma: {rotation: 0.002, translation: 0.002}   # optional: per-frame VO noise (drift model)
      particles: 5000                  # default
      seed: 0                          # default

The nominal initial lengths come from the description's offsets: L0_i = z_i[0] - nominal l0_i.
Pulley, offset and scale initial values are replaced (the description's values are not used).
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (cable_robot, Initializer, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSITIVE_SCHEMA as POSITIVE, Spec,
                           TOLERANCE_SCHEMA, fit_range_origin, interpolate_poses, nearest)

from .factors import check_cdpr, length_columns
from .monte_carlo import CONVERGED_SPREAD, Calibration, calibrate

VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
MIN_SAMPLES = 10
EDGE_SHARE = 0.3  # share of the L0 belief in the outer tenth of its prior that flags the edge (uniform: 0.1)
AXIS_NAMES = ("x", "y", "z")
STAGE_NAMES = ("after the first axis (shell)", "after the second axis (ring)", "end (cluster)")


def _direction(v: np.ndarray) -> str:
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) >= np.cos(np.radians(20.0)):
        return AXIS_NAMES[i]
    v = v * np.sign(v[i])
    return "[" + ", ".join(f"{x:.2f}" for x in v) + "]"


class MonteCarloCalibration(Initializer):
    name = "cable.monte_carlo"
    summary = ("Monte-Carlo self-calibration: pulleys, encoder offsets and VO scale from the encoders and "
               "unscaled VO alone (annealed particle belief: shell -> ring -> cluster)")
    robot_fields = ("robot",)
    stream_fields = ("stream", "lengths")
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "lengths": {"type": "string"},
                             "columns": {"type": "array", "items": {"type": "string"}},
                             "region": {"type": "object", "properties": {"min": VEC3, "max": VEC3},
                                        "required": ["min", "max"], "additionalProperties": False},
                             "scale_range": {"type": "array", "items": POSITIVE, "minItems": 2, "maxItems": 2},
                             "scale": {"type": "string"}, "sigma": POSITIVE,
                             "initial_length_spread": {**POSITIVE, "default": 0.05},
                             "vo_sigma": {"type": "object",
                                          "properties": {"rotation": NONNEG, "translation": NONNEG},
                                          "additionalProperties": False,
                                          "default": {"rotation": 0.0, "translation": 0.0}},
                             "particles": {"type": "integer", "minimum": 100, "default": 5000},
                             "seed": {"type": "integer", "minimum": 0, "default": 0},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "lengths", "region", "scale_range", "scale", "sigma"],
              "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        n = check_cdpr(spec, scope)
        scope.require_states(spec, "robot", "pose3")
        scope.require_columns(spec, "stream", POSE_COLUMNS)
        if "columns" in spec.data and len(spec["columns"]) != n:
            raise spec.error("columns", f"{len(spec['columns'])} columns named; the robot has {n} cables")
        scope.require_columns(spec, "lengths", tuple(length_columns(spec, n)))
        scope.require_parameter(spec, "robot", "scale", "scalar")
        scope.require_values(spec, "robot", "offset", "to guess the first cable lengths")
        lo, hi = np.asarray(spec["region"]["min"]), np.asarray(spec["region"]["max"])
        if np.any(lo >= hi):
            axis = AXIS_NAMES[int(np.argmax(lo >= hi))]
            raise spec.error("region", f"region min must be below max on every axis ({axis} is not)")
        s0, s1 = spec["scale_range"]
        if s0 > s1:
            raise spec.error("scale_range", f"expected [min, max]; got [{s0}, {s1}]")

    def initialize(self, ctx, spec: Spec) -> None:
        from scipy.spatial.transform import Rotation
        robot = spec["robot"]
        desc = ctx.robot(robot)
        cdpr = cable_robot(desc)
        states = ctx.state_set(robot, spec)
        ks, z = length_samples(ctx, spec, states.t, cdpr.n)

        # end-effector poses X0 o (R_k, s t_k): VO relative to state 0, at the state times
        vo = ctx.stream(spec["stream"])
        t = np.clip(np.concatenate([states.t[:1], states.t[ks]]), vo.t[0], vo.t[-1])
        _, arr = interpolate_poses(vo.t, vo.pose_array(), t)
        R = Rotation.from_quat(arr[:, 3:]).as_matrix()
        R_rel = np.einsum("ji,kjl->kil", R[0], R[1:])
        t_rel = np.einsum("ji,kj->ki", R[0], arr[1:, :3] - arr[0, :3])
        X0 = ctx.initial_value(ctx.pose_key(robot, 0))
        R0, p0 = X0.rotation().matrix(), np.asarray(X0.translation())
        c = np.einsum("ij,kjl,cl->cki", R0, R_rel, cdpr.attachments) + p0
        d = t_rel @ R0.T
        nominal = np.asarray(desc.parameters["offset"].values, float)
        L0_guess = z[:, 0] - nominal
        frames = np.searchsorted(vo.t, t[1:], side="right") - np.searchsorted(vo.t, t[0], side="right")
        vo_sigma = spec["vo_sigma"]
        try:
            cal = calibrate(c, d, z, L0_guess, (spec["region"]["min"], spec["region"]["max"]),
                            tuple(spec["scale_range"]), float(spec["sigma"]),
                            spread=float(spec["initial_length_spread"]), particles=int(spec["particles"]),
                            rng=np.random.default_rng(spec["seed"]),
                            vo_sigma=(float(vo_sigma["rotation"]), float(vo_sigma["translation"])), frames=frames)
        except ValueError as exc:
            raise spec.error("region", f"{exc}: widen the region or initial_length_spread, or check the "
                             "nominal offsets") from None

        offsets = z[:, 0] - cal.length
        for i in range(cdpr.n):
            ctx.set_initial(ctx.parameter(robot, "pulley", i), np.asarray(cal.pulley[i], float))
            ctx.set_initial(ctx.parameter(robot, "offset", i), float(offsets[i]))
        ctx.set_initial(ctx.parameter(robot, spec["scale"]), float(cal.scale))
        report = diagnostic(cal, offsets, spec, states.t[ks])
        ctx.add_diagnostic(spec.label, report)
        ctx.add_plot("monte_carlo_belief", lambda path: draw_belief(cal, path))


def length_samples(ctx, spec: Spec, t: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The states with an encoder sample of stream `lengths` (nearest stamp within `tolerance`)
    and the readings there: (state indices (K,), lengths (n, K) in m)."""
    lengths = ctx.stream(spec["lengths"])
    assoc = nearest(t, lengths.t, spec["tolerance"])
    if len(assoc.state) < MIN_SAMPLES:
        raise spec.error("lengths", f"only {len(assoc.state)} samples of stream {lengths.name!r} match a state "
                         f"of {spec['robot']!r}; {spec.type} needs at least {MIN_SAMPLES}")
    z = np.array([lengths.column(col)[assoc.row] for col in length_columns(spec, n)])
    return assoc.state, z


class Multilateration(Initializer):
    name = "cable.multilateration"
    summary = ("pulleys and encoder offsets from known end-effector poses (motion capture) and the encoders: "
               "closed-form sphere fit per cable")
    robot_fields = ("robot",)
    stream_fields = ("lengths",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "lengths": {"type": "string"},
                             "columns": {"type": "array", "items": {"type": "string"}},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "lengths"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        n = check_cdpr(spec, scope)
        scope.require_states(spec, "robot", "pose3")
        scope.require_columns(spec, "lengths", tuple(length_columns(spec, n)))

    def initialize(self, ctx, spec: Spec) -> None:
        """Cable i: z_ik = ||R_k b_i + t_k - a_i|| + l0_i at the poses' current initial values
        (place it after the initializer that sets them, e.g. pose.interpolate of the mocap)."""
        robot = spec["robot"]
        cdpr = cable_robot(ctx.robot(robot))
        ks, z = length_samples(ctx, spec, ctx.state_set(robot, spec).t, cdpr.n)
        poses = [ctx.initial_value(ctx.pose_key(robot, int(k))) for k in ks]
        R = np.array([p.rotation().matrix() for p in poses])
        t = np.array([p.translation() for p in poses])
        lines = []
        for i in range(cdpr.n):
            try:
                a, l0, rms = fit_range_origin(R @ cdpr.attachments[i] + t, z[i])
            except ValueError as exc:
                raise spec.error("lengths", f"cable {i}: {exc}") from None
            ctx.set_initial(ctx.parameter(robot, "pulley", i), a)
            ctx.set_initial(ctx.parameter(robot, "offset", i), l0)
            lines.append(f"cable {i}: pulley ({', '.join(f'{x:.3f}' for x in a)}), offset {l0:.4f} m; "
                         f"fit rms {rms * 1e3:.2f} mm over {len(ks)} poses")
        ctx.add_diagnostic(spec.label, {"verdict": lines})


def diagnostic(cal: Calibration, offsets: np.ndarray, spec: Spec, t: np.ndarray) -> dict:
    """Per-cable estimates with their 1-sigma spreads, the scale, the stages, plain verdicts."""
    s0, s1 = spec["scale_range"]
    lo, hi = np.asarray(spec["region"]["min"], float), np.asarray(spec["region"]["max"], float)
    principal = cal.principal_spread()
    n_axes = cal.axes_covered
    lines = [(f"VO scale {cal.scale:.4f} +- {cal.scale_sigma:.4f} from {len(offsets)} cables; the motion covers "
              f"{n_axes} ax{'i' if n_axes == 1 else 'e'}s ({cal.particles} particles, {cal.seconds:.2f} s)")]
    cables = []
    for i in range(len(offsets)):
        sig = np.sqrt(np.clip(np.diag(cal.pulley_cov[i]), 0, None))
        resolved = bool(principal[i, 0] <= CONVERGED_SPREAD)
        widest = np.linalg.eigh(cal.pulley_cov[i])[1][:, -1]
        cables.append({"cable": i, "pulley": cal.pulley[i].tolist(), "pulley_sigma": sig.tolist(),
                       "principal_spread_m": principal[i].tolist(), "widest_direction": widest.tolist(),
                       "offset": float(offsets[i]), "offset_sigma": float(cal.length_sigma[i]),
                       "initial_length": float(cal.length[i]), "fit_rms_m": float(cal.fit_rms[i]),
                       "scale_alone": cal.scale_per_cable[i].tolist(),
                       "stage_spread_m": cal.stage_spread[:, i].tolist(), "resolved": resolved})
        where = ", ".join(f"{x:.3f}" for x in cal.pulley[i])
        if not resolved:
            lines.append(f"cable {i}: pulley NOT resolved by this motion: the belief still spreads "
                         f"{principal[i, 0]:.2f} m (1 sigma) along {_direction(widest)}; its mean ({where}) is only "
                         "a placeholder -- move the end-effector along more axes")
            continue
        lines.append(f"cable {i}: pulley ({where}) +- {principal[i, 0]:.3f} m, offset {offsets[i]:.4f} "
                     f"+- {cal.length_sigma[i]:.4f} m")
        if cal.length_at_edge[i] > EDGE_SHARE:
            lines.append(f"cable {i}: the initial length presses against the edge of +-{cal.spread} m around the "
                         "nominal one (from the description's offset): widen initial_length_spread, or the VO "
                         "drifts more than vo_sigma says")
        if np.any(cal.pulley[i] - 2 * sig <= lo) or np.any(cal.pulley[i] + 2 * sig >= hi):
            lines.append(f"cable {i}: the pulley belief touches the region's boundary: widen the region")
    if not s0 + 2 * cal.scale_sigma < cal.scale < s1 - 2 * cal.scale_sigma:
        lines.append(f"the VO scale belief touches scale_range [{s0}, {s1}]: widen it")
    if cal.scale_consistency > 4.0:
        lines.append(f"the cables disagree on the VO scale ({cal.scale_consistency:.1f} times their own variances; "
                     "VO drift?): its sigma is inflated to match")
    return {"particles": cal.particles, "seconds": cal.seconds, "poses": int(cal.stage_poses[-1]),
            "scale": {"value": cal.scale, "sigma": cal.scale_sigma, "per_cable": cal.scale_per_cable.tolist(),
                      "consistency": cal.scale_consistency},
            "stages": {"names": list(STAGE_NAMES), "poses": list(cal.stage_poses),
                       "end_time_s": [float(t[p - 1]) for p in cal.stage_poses], "axes_covered": n_axes},
            "cables": cables, "verdict": lines}


def draw_belief(cal: Calibration, path) -> None:
    """plots/monte_carlo_belief.png: per cable (rows), the pulley particles after the first axis of
    motion, after the second and at the end (x-y and x-z projections), with the final estimate."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(cal.pulley)
    names = STAGE_NAMES
    fig, axes = plt.subplots(n, 6, figsize=(19, 3.0 * n + 0.8), squeeze=False)
    for i in range(n):
        for j in range(3):
            pts = cal.clouds[j][i]
            spread = cal.stage_spread[j, i]
            for k, (a, b) in enumerate(((0, 1), (0, 2))):
                ax = axes[i, 2 * j + k]
                ax.scatter(pts[a], pts[b], s=1.5, alpha=0.5, color=f"C{i}", rasterized=True)
                ax.plot(cal.pulley[i, a], cal.pulley[i, b], "k+", markersize=10, mew=1.5)
                ax.set_xlabel(f"{AXIS_NAMES[a]} [m]", fontsize=8)
                ax.set_ylabel(f"{AXIS_NAMES[b]} [m]", fontsize=8)
                ax.tick_params(labelsize=7)
                if k == 0:
                    ax.set_title(f"cable {i}, {names[j]}\n1 sigma " + " x ".join(f"{s:.3g}" for s in spread) + " m",
                                 fontsize=8, loc="left")
    fig.suptitle(f"Monte-Carlo belief of the pulleys (+: final estimate); VO scale {cal.scale:.4f} "
                 f"+- {cal.scale_sigma:.4f}; stages end at poses {', '.join(map(str, cal.stage_poses))}", fontsize=10)
    fig.subplots_adjust(left=0.04, right=0.99, bottom=0.05, top=1 - 0.75 / fig.get_figheight(),
                        wspace=0.35, hspace=0.55)  # fixed margins: tight_layout costs ~2 s on 24 axes
    fig.savefig(path, dpi=90)
    plt.close(fig)


INITIALIZERS = [MonteCarloCalibration, Multilateration]
