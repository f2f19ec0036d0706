"""Observability of the cable calibration from a trajectory (thesis eqs. 4.6-4.7;
docs/models/cable_rigid.md#observability).

Derivation
----------
Cable i at sample k (rigid: alpha_k = 1; elastic: alpha_k = 1 - T_k/EA, known from the force
sensor), with p_k = R_k b + t_k the attachment point in the world frame:

    z_k = alpha_k ||p_k - a|| + l0            =>     (z_k - l0)^2 = alpha_k^2 ||p_k - a||^2

Centre the data (p~_k = p_k - mean p, z~_k = z_k - mean z) and the unknowns with them
(a~ = a - mean p, l0~ = l0 - mean z): an invertible change of unknowns, so the rank is unchanged,
but the conditioning no longer depends on where the world origin is. Expanding,

    z~^2 - 2 z~ l0~ + l0~^2 = alpha^2 |p~|^2 - 2 alpha^2 p~.a~ + alpha^2 |a~|^2

is linear in monomials of the unknowns.

Known scale (metric poses, e.g. motion capture); exact, rotations included:

    [-2 alpha^2 p~^T, 2 z~, alpha^2, -1] . [a~, l0~, |a~|^2, l0~^2] = z~^2 - alpha^2 |p~|^2

Rigid (or constant alpha) the last two columns are proportional and merge into one unknown,
c = |a~|^2 - l0~^2: rows [-2 p~^T, 2 z~, 1] . [a~, l0~, c] = z~^2 - |p~|^2 (5 unknowns).

Unknown scale (monocular VO, thesis eq. 4.3: translations t_k known up to the factor s). With a constant
orientation the attachment point is p_k = s t_k + r, r = R b, and p_k - a = s t~_k - a~ with
a~ = a - r - s mean(t):

    [-2 alpha^2 t~^T, alpha^2 |t~|^2, 2 z~, alpha^2, -1] . [s a~, s^2, l0~, |a~|^2, l0~^2] = z~^2

rigid: [-2 t~^T, |t~|^2, 2 z~, 1] . [s a~, s^2, l0~, |a~|^2 - l0~^2] = z~^2 -- the six unknowns
(s a, s^2, l0, |a|^2 - l0^2) of thesis eq. 4.7. The thesis prints alpha where the expansion gives alpha^2,
and its single constant column holds only for a constant alpha. When the orientation varies,
r_k = r + d_k and each row misses -2 alpha^2 d_k.(a~ - s t~_k) + alpha^2 |d_k|^2; lifting those
terms would add four unknowns duplicating a~ and s, so they are left out: this acts like an
encoder error of about |d_k| = |(R_k - mean R) b| (mm for a swinging end-effector).
Recovery: s = sqrt(theta[s^2]), a = theta[s a~] / s + s mean(t) + r (known scale:
a = a~ + mean p), l0 = l0~ + mean z.

Rank and conditioning
---------------------
Columns are scaled per unit, not one by one: length columns (-2 p~, 2 z~) by 1/(2 L), with
L = rms |p~| the size of the motion, square-length ones (|t~|^2) by 1/L^2, dimensionless ones
by 1; rows by 1/sqrt(N). A per-column normalization would blow a millimetre wobble along z up to
full weight; a shared length scale keeps the anisotropy of the motion. Then sigma_j * L is the
rms amplitude (m) of the least-explained combination of motion, and a direction counts as
excited when it exceeds the encoder noise: sigma_j > k sigma_enc / L (k = 3) -- the tolerance
relative to the largest singular value is k sigma_enc / (L sigma_max).
Pulley, offset (and scale) are observable when the numerical null space does not touch them:
rank(A) - rank(nuisance columns) equals their number (rigid: the same as full rank).
Advice: the eigenvectors of the attachment-point covariance whose rms extent is below
k sigma_enc (their pulley column then has a singular value below the tolerance) are the spatial
part of the null space, named as axes (within 20 deg) or vectors. A null space without them
means l0 (and s) trade against the distance to the pulley along the cable: the motion is too
small for the sphere's curvature to show. `weakest_direction` is the pulley part of the weakest
singular vector (with a shared length scale it is a direction in space; for a good trajectory
it points along the cable), or the smallest-extent axis when that part is small.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusionkit.api import cable_robot, nearest, Spec


AXES = ("x", "y", "z")
ADVICE = {"x": "x", "y": "y", "z": "z (up/down)"}
K_NOISE = 3.0  # a direction is excited when its rms amplitude exceeds K_NOISE encoder sigmas
MISMATCH = 2.0  # a fit rms above MISMATCH encoder sigmas: the model misses something, judge at that level
AXIS_COS = np.cos(np.radians(20.0))  # a direction within 20 deg of an axis is named by the axis


@dataclass
class LiftedSystem:
    """The linear system A theta = rhs of the squared measurement (see the module docstring)."""

    A: np.ndarray          # (N, n) unscaled
    rhs: np.ndarray        # (N,)
    unknowns: tuple[str, ...]
    interest: int          # the first `interest` unknowns matter (pulley, scale, offset); the rest are nuisance
    col_scale: np.ndarray  # (n,) per-unit column scaling
    L: float               # rms size of the motion (m)
    q: np.ndarray          # (N, 3) attachment points (known scale) or translations (unknown scale)
    q_mean: np.ndarray
    z_mean: float
    shift: np.ndarray      # unknown scale: mean rotated attachment R b added back to the pulley
    unknown_scale: bool
    z: np.ndarray          # (N,) the encoder readings
    alpha: np.ndarray      # (N,) 1 - T/EA (ones: rigid)


def lifted_system(t: np.ndarray, z: np.ndarray, attachment: np.ndarray | None = None,
                  alpha: np.ndarray | None = None, unknown_scale: bool = False) -> LiftedSystem:
    """Rows of the squared measurement for one cable.

    t: (N, 3) end-effector positions; attachment: (N, 3) R_k b (world-frame attachment offsets);
    z: (N,) encoder readings; alpha: (N,) 1 - T/EA (None: rigid)."""
    t, z = np.asarray(t, float), np.asarray(z, float)
    r = np.zeros_like(t) if attachment is None else np.asarray(attachment, float)
    q, shift = (t, r.mean(axis=0)) if unknown_scale else (t + r, np.zeros(3))
    q_mean, z_mean = q.mean(axis=0), float(z.mean())
    qc, zc = q - q_mean, z - z_mean
    L = float(np.sqrt(np.mean(np.sum(qc ** 2, axis=1))))
    N, unit = len(z), 1 / (2 * L) if L > 0 else 1.0  # length columns carry a factor 2
    elastic = alpha is not None and np.ptp(alpha) > 0
    a2 = np.ones(N) if alpha is None else np.asarray(alpha, float) ** 2
    cols = [-2 * a2[:, None] * qc]
    names = ["a_x", "a_y", "a_z"] if not unknown_scale else ["s*a_x", "s*a_y", "s*a_z"]
    scales = [[unit] * 3]
    if unknown_scale:
        cols.append((a2 * np.sum(qc ** 2, axis=1))[:, None])
        names.append("s^2")
        scales.append([4 * unit ** 2])
    cols.append(2 * zc[:, None])
    names.append("l0")
    scales.append([unit])
    interest = len(names)
    if elastic:
        cols.append(np.column_stack([a2, -np.ones(N)]))
        names += ["|a|^2", "l0^2"]
        scales.append([1.0, 1.0])
    else:
        # constant alpha: alpha^2 |a|^2 - l0^2 = alpha^2 (|a|^2 - l0^2 / alpha^2), one column
        cols.append(a2[:, None])
        names.append("|a|^2-l0^2" if alpha is None else "|a|^2-l0^2/alpha^2")
        scales.append([1.0])
    rhs = zc ** 2 - (0 if unknown_scale else a2 * np.sum(qc ** 2, axis=1))
    return LiftedSystem(np.column_stack(cols), rhs, tuple(names), interest, np.concatenate(scales), L,
                        q, q_mean, z_mean, shift, unknown_scale, z, np.sqrt(a2))


def solve_lifted(sys: LiftedSystem) -> dict:
    """Least-squares solution mapped back to the pulley a (world), offset l0 and scale s."""
    theta = sys.col_scale * np.linalg.lstsq(sys.A * sys.col_scale, sys.rhs, rcond=None)[0]
    l0 = float(theta[sys.interest - 1] + sys.z_mean)
    if not sys.unknown_scale:
        return {"pulley": theta[:3] + sys.q_mean, "offset": l0, "scale": 1.0}
    s = float(np.sqrt(max(theta[3], 0.0)))
    return {"pulley": theta[:3] / s + s * sys.q_mean + sys.shift, "offset": l0, "scale": s}


def fit_rms(sys: LiftedSystem, iterations: int = 30) -> float:
    """Rms (m) of the length residuals alpha |q - a| + l0 - z at the least-squares pulley and offset: the
    lifted solution refined by Gauss-Newton on the lengths themselves, a step halved while it raises the
    cost. nan with an unknown scale, or when the refinement has not converged (no verdict rests on it)."""
    if sys.unknown_scale:
        return float("nan")
    first = solve_lifted(sys)
    x = np.r_[np.asarray(first["pulley"], float), first["offset"]]

    def residual(x):
        return sys.alpha * np.linalg.norm(sys.q - x[:3], axis=1) + x[3] - sys.z
    e = residual(x)
    for _ in range(iterations):
        d = sys.q - x[:3]
        dist = np.linalg.norm(d, axis=1)
        J = np.column_stack([-(sys.alpha / np.maximum(dist, 1e-9))[:, None] * d, np.ones(len(e))])
        step = np.linalg.lstsq(J, -e, rcond=None)[0]
        while True:
            trial = residual(x + step)
            if trial @ trial <= e @ e or np.abs(step).max() < 1e-12:
                break
            step = step / 2
        x, e = x + step, trial
        if np.abs(step).max() < 1e-9:
            return float(np.sqrt(np.mean(e ** 2)))
    return float("nan")


def _rank(s: np.ndarray, tol: float) -> int:
    return int(np.sum(s > tol))


def analyze(sys: LiftedSystem, sigma: float, k: float = K_NOISE, fit: bool = True) -> dict:
    """Rank, condition, weak directions of one cable's system (sigma: encoder noise, m). When the motion
    determines the pulley and offset at that noise but the lengths fit it far worse (rms above MISMATCH
    sigmas: sag, swing, a pulley radius or a time offset the model lacks), it is judged again against that
    residual level (`judged_at_m`). `fit`: False for a robot the fit's model does not describe (pulleys
    with a radius)."""
    r = _analyze(sys, sigma, k)
    residual = fit_rms(sys) if r["observable"] and fit else float("nan")
    if residual > MISMATCH * sigma:  # (nan compares False)
        r = _analyze(sys, residual, k)
    return {**r, "fit_rms_m": residual, "judged_at_m": residual if residual > MISMATCH * sigma else sigma}


def _analyze(sys: LiftedSystem, sigma: float, k: float) -> dict:
    n, N = sys.A.shape[1], sys.A.shape[0]
    As = sys.A * sys.col_scale / np.sqrt(max(N, 1))
    _, s, Vt = np.linalg.svd(As, full_matrices=True)
    s = np.concatenate([s, np.zeros(n - len(s))])  # fewer samples than unknowns
    tol = max(k * sigma / sys.L if sys.L > 0 else np.inf, s[0] * n * np.finfo(float).eps)
    rank = _rank(s, tol)
    nuisance = np.linalg.svd(As[:, sys.interest:], compute_uv=False)
    observable = rank - _rank(nuisance, tol) == sys.interest
    condition = float(s[0] / max(s[-1], s[0] * np.finfo(float).eps))
    rms, dirs = _spread(sys.q)
    # axes of the attachment cloud whose rms extent is below the noise threshold are the spatial
    # part of the null space (their pulley column has a singular value below the tolerance)
    spatial = 0 if observable else min(n - rank, int(np.sum(rms <= k * sigma)))
    weakest = Vt[-1, :3]  # pulley part of the weakest combination (shared length scale: a direction)
    if np.linalg.norm(weakest) > 0.3:
        weakest = weakest / np.linalg.norm(weakest)
        weakest = weakest * np.sign(weakest[np.argmax(np.abs(weakest))])
    else:
        weakest = dirs[:, 0]
    return {"rank": rank, "unknowns": n, "condition": condition, "observable": bool(observable),
            "weakest_direction": weakest, "missing_directions": dirs[:, :spatial],
            "excitation_m": float(s[-1] * sys.L), "extent_m": np.ptp(sys.q, axis=0), "samples": N,
            "unknown_names": sys.unknowns}


def _spread(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigen-decomposition of the attachment-point covariance, smallest first: rms extents (m)
    and unit directions (columns, largest component positive)."""
    w, v = np.linalg.eigh(np.cov(q.T) if len(q) > 1 else np.zeros((3, 3)))
    v = v * np.sign(v[np.argmax(np.abs(v), axis=0), range(3)])
    return np.sqrt(np.clip(w, 0, None)), v


def direction_name(d: np.ndarray) -> str:
    """The nearest axis when within 20 deg, else the unit vector."""
    i = int(np.argmax(np.abs(d)))
    return AXES[i] if abs(d[i]) >= AXIS_COS else "[" + ", ".join(f"{round(c, 2) + 0.0:.2f}" for c in d) + "]"


def subspace_names(M: np.ndarray) -> list[str]:
    """Names of the unexcited subspace (orthonormal columns M): the axes lying in it (within
    20 deg), then vectors for what they leave -- a degenerate eigenbasis is not axis-aligned."""
    axes = [j for j in range(3) if np.sqrt((M @ M.T)[j, j]) >= AXIS_COS]
    E = np.eye(3)[:, axes]
    u = np.linalg.svd(M - E @ (E.T @ M))[0][:, :M.shape[1] - len(axes)]
    u = u * np.sign(u[np.argmax(np.abs(u), axis=0), range(u.shape[1])])
    return [AXES[j] for j in axes] + [direction_name(v) for v in u.T]


def _sci(x: float) -> str:
    mantissa, exp = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exp)}"


def _join(words: list[str]) -> str:
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def verdict(cable: int, r: dict) -> str:
    head = f"cable {cable}: "
    if r.get("fit_rms_m", 0.0) == r.get("judged_at_m", -1.0):
        head += (f"the lengths fit this motion to {r['fit_rms_m'] * 1e3:.1f} mm rms, more than {MISMATCH:g} encoder "
                 "sigmas: the model misses something (sagging cables, a swinging end-effector, pulley radius, a "
                 "time offset); judged at that level, ")
    counts = f"rank {r['rank']}/{r['unknowns']}, condition {_sci(r['condition'])}"
    if r["observable"]:
        return head + f"observable ({counts})" + ("" if r["rank"] == r["unknowns"] else
                                                   "; the tension varies too little to separate |a|^2 from "
                                                   "l0^2, which the pulley and offset do not need")
    span = " x ".join(f"{e:.2f}" for e in r["extent_m"])
    head += f"NOT observable from this trajectory ({counts}): "
    if r["samples"] < r["unknowns"]:
        return head + f"only {r['samples']} samples for {r['unknowns']} unknowns; record more"
    if r["missing_directions"].shape[1]:
        names = subspace_names(r["missing_directions"])
        along = _join([ADVICE.get(n, n) for n in names])
        return (head + f"the motion does not excite it along {_join(names)} (the attachment points "
                f"span {span} m in x, y, z); move the end-effector along {along} as well")
    return (head + f"the motion (attachment points spanning {span} m in x, y, z) is too small to tell the "
            "offset" + (" and scale" if "s^2" in r["unknown_names"] else "") + " from the distance to the "
            "pulley; cover a larger volume, moving across the cable direction")


def _poses(ctx, states, ks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    poses = [ctx.initial_value(states.key(int(k))) for k in ks]
    return (np.array([p.rotation().matrix() for p in poses]).reshape(-1, 3, 3),
            np.array([p.translation() for p in poses]).reshape(-1, 3))


def scale_unknown(ctx, robot: str) -> bool:
    """Poses are known only up to scale when some entry estimates a scale for the robot
    (e.g. pose.scaled_relative's `scale:`): the conservative check then adds s^2."""
    return any("scale" in s.data for s in ctx.entries(robot=robot))


def diagnose_cable_lengths(ctx, spec: Spec, alpha_of=None) -> dict:
    """The observability diagnostic of a cable.length entry, from the initial pose estimates and
    the measured lengths associated as the factor does. `alpha_of(i, states)`: elastic alpha."""
    from .factors import length_columns

    robot = spec["robot"]
    cdpr = cable_robot(ctx.robot(robot))
    stream, states = ctx.stream(spec["stream"]), ctx.state_set(robot, spec)
    assoc = nearest(states.t, stream.t, spec["tolerance"])
    have = np.array([ctx.has_variable(states.key(int(k))) for k in assoc.state], dtype=bool)
    ks, rows = assoc.state[have], assoc.row[have]
    R, t = _poses(ctx, states, ks)
    unknown = scale_unknown(ctx, robot)
    columns = length_columns(spec, cdpr.n)
    cables, lines = [], []
    for i in spec.get("cables", range(cdpr.n)):
        if len(ks) < 2:
            lines.append(f"cable {i}: NOT observable: {len(ks)} length samples matched an initialized state")
            cables.append({"cable": int(i), "rank": 0, "unknowns": 5 + unknown, "observable": False})
            continue
        sys = lifted_system(t, stream.column(columns[i])[rows], R @ cdpr.attachments[i],
                            None if alpha_of is None else alpha_of(i, ks), unknown)
        r = analyze(sys, float(spec["sigma"]), fit=cdpr.pulley_radius == 0)
        cables.append({"cable": int(i), "rank": r["rank"], "unknowns": r["unknowns"],
                       "condition": r["condition"], "extent_m": [float(e) for e in r["extent_m"]],
                       "weakest_direction": [float(c) for c in r["weakest_direction"]],
                       "excitation_m": r["excitation_m"], "observable": r["observable"],
                       "fit_rms_m": None if np.isnan(r["fit_rms_m"]) else r["fit_rms_m"],
                       "unknown_names": list(r["unknown_names"])})
        lines.append(verdict(int(i), r))
    report = {"cables": cables, "verdict": lines}
    ctx.add_diagnostic(spec.label, report, identifiability=True)
    return report
