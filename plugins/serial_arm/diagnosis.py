"""The identifiability diagnostic of a serial arm in a run: the kinematic regressor of every marker
entry of the robot at the joint readings and the nominal parameters with the base and tool fitted to the entry's
data (frames.frame_fit: a marker at the URDF's tool origin would hide the last wrist offset), the parameters to hold, the
hold factors, and the verdict in words (docs/models/serial_arm.md#identifiability).

Held parameters (tangent axes) get a prior of HOLD_SIGMA at their nominal value: FIGAROH's "base
parameters" (a minimal set the data determine). The forward kinematics, and so every prediction, is
the same as with any other split of an unidentifiable combination; holding makes the estimate unique
and its sigmas honest (a split decided by the priors would report the priors' sigma as if measured).
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import gaussian, Spec

from .frames import frame_fit
from .identifiability import analyze, kinematic_regressor
from .kinematics import Layout, parameters_of
from .model import AXIS_NAMES, group_joints
from .residuals import held_axes_residual

HOLD_SIGMA = 1e-9  # prior sigma (SI units per axis) holding an unidentifiable parameter at its nominal value
MARKER_TYPES = ("arm.tool_pose", "arm.tool_position", "arm.relative_tool_pose")
ROLE = {"base": 0, "tool": 1, "offset": 2, "placement": 3, "compliance": 4, "mass_compliance": 5}  # the priority of the regressor's columns


def _hold_error(vartype: str, value, axes: list[int], this, v: gtsam.Values, H):
    key = this.keys()[0]
    x = v.atPose3(key) if vartype == "pose3" else v.atDouble(key) if vartype == "scalar" else v.atVector(key)
    return held_axes_residual(vartype, value, x, axes, H)


def hold_factor(key: int, vartype: str, value, axes: list[int], sigma: float = HOLD_SIGMA) -> gtsam.CustomFactor:
    """Holds the tangent `axes` of variable `key` at `value` (vartype pose3, vector or scalar)."""
    return gtsam.CustomFactor(gaussian([sigma] * len(axes)), [key], partial(_hold_error, vartype, value, axes))


def parameter_axes(layout: Layout, variables: list, desc, chain) -> list[tuple]:
    """(role, parameter, index, [(axis position, axis label, unit)]) of each layout variable."""
    roles = ["base"] * layout.base + ["tool"] * bool(layout.tool) + ["offset"] * len(layout.offsets) + \
        ["placement"] * len(layout.placements) + ["compliance"] * len(layout.compliances) + \
        ["mass_compliance"] * len(layout.mass_compliances)
    joint = [None] * (layout.base + bool(layout.tool)) + list(layout.offsets) + [j for j, _ in layout.placements] \
        + list(layout.compliances) + list(layout.mass_compliances)  # each variable's joint
    group_axes = [None] * (layout.base + bool(layout.tool) + len(layout.offsets)) + [a for _, a in layout.placements]
    out = []
    for p, (role, (name, index)) in enumerate(zip(roles, variables)):
        vt = desc.parameters[name].vartype.name
        j = joint[p]
        if role in ("base", "tool"):
            labels = AXIS_NAMES if vt == "pose3" else ("tx", "ty", "tz")
            axes = [(a, f".{lab}", "rad" if lab[0] == "r" else "m") for a, lab in enumerate(labels)]
        elif role == "offset":
            axes = [(0, "", "m" if chain.prismatic[j] else "rad")]
        elif role == "compliance":
            axes = [(0, "", "m/N" if chain.prismatic[j] else "rad/(N m)")]
        elif role == "mass_compliance":
            unit = "m kg/N" if chain.prismatic[j] else "rad kg/(N m)"
            axes = [(a, f".{link}", unit) for a, (link, *_) in enumerate(layout.lumped)]
        else:
            axes = [(a, f".{AXIS_NAMES[g]}", "rad" if g < 3 else "m") for a, g in enumerate(group_axes[p])]
        out.append((role, name, index, axes))
    return out


def element_name(desc, name: str, index: int | None) -> str:
    """`joint_offsets[elbow_joint]` for a kinematic group's element, `base` for a single parameter: as the
    summary, report.json and calibration.yaml name it (SerialArmModel.element_names)."""
    if index is None:
        return name
    joints = group_joints(desc.extra, name)
    return f"{name}[{joints[index] if joints else index}]"


def identify(ctx, spec: Spec) -> dict | None:
    """Run by a marker entry's diagnose: only the robot's first marker entry analyses them all."""
    robot = spec["robot"]
    entries = sorted((s for t in MARKER_TYPES for s in ctx.entries(t, robot)), key=lambda s: s.path)
    if entries[0].path != spec.path:
        return None
    desc = ctx.robot(robot)
    A, info, used_ks, configurations = _regressor(ctx, robot, desc, entries)
    if not info:
        return None
    scale = np.array([prior_sigma(desc, name, index, a) for _, name, index, a, _, _ in info])
    result = analyze(A, np.where(np.isfinite(scale), scale, 1.0))
    names = [element_name(desc, name, index) + label for _, name, index, _, label, _ in info]
    _hold(ctx, robot, desc, info, result, names, used_ks)
    report = {"configurations": configurations, "rows": int(A.shape[0]), "parameters": names,
              "rank": result.rank, "held": [names[h] for h in result.held],
              "combinations": {names[h]: {names[j]: c for j, c in result.combinations[h]} for h in result.held},
              "sigma_from_data": {names[j]: float(result.sigma[j]) for j in range(len(names)) if j not in result.held},
              "condition": result.condition, "verdict": verdict(result, names, info, scale, configurations)}
    ctx.add_diagnostic(f"{robot}: kinematic identifiability", report, identifiability=True)
    return report


def _regressor(ctx, robot: str, desc, entries: list[Spec]) -> tuple[np.ndarray, list[tuple], dict, int]:
    """The regressor of all marker entries (columns: every parameter axis any of them uses, not fixed, in
    priority order), each column's (role, parameter, index, axis position, label, unit), the states at
    which each parameter is used, and the number of configurations."""
    from .factors import FACTOR_TYPES, entry_arm
    types = {cls.name: cls() for cls in FACTOR_TYPES}
    columns: dict[tuple, int] = {}
    info: list[tuple] = []
    pieces, used_ks, configurations = [], {}, set()
    for entry in entries:
        ftype = types[entry.type]
        layout, variables = ftype.layout(ctx, entry)
        chain = entry_arm(desc, entry).chain
        ks, rows = ftype.samples(ctx, entry)
        if not len(ks):
            continue
        q = np.array([[ctx.initial_value(ctx.state_key(robot, int(k))) for k in np.atleast_1d(pair)] for pair in ks])
        configurations.update(np.unique(ks).tolist())
        nominal = parameters_of(layout, [desc.parameters[name].values[index or 0] for name, index in variables])
        joints = q if ftype.kind == "relative" else q[:, 0]
        point = frame_fit(chain, layout, nominal, joints, ftype.measured(ctx.stream(entry["stream"]), rows, entry),
                          ftype.kind)
        A = kinematic_regressor(chain, layout, point, joints, ftype.kind, ftype.sigmas(entry))
        targets, c = [], 0
        for role, name, index, axes in parameter_axes(layout, variables, desc, chain):
            used_ks.setdefault((name, index), set()).update(np.asarray(ks).reshape(len(ks), -1)[:, -1].tolist())
            for a, label, unit in axes:
                if not desc.parameters[name].fixed:
                    col = columns.setdefault((name, index, a), len(columns))
                    if col == len(info):
                        info.append((role, name, index, a, label, unit))
                    targets.append((c, col))
                c += 1
        pieces.append((A, targets))
    order = sorted(range(len(info)), key=lambda col: (ROLE[info[col][0]], col))  # base, tool, offsets, placements, compliances, mass compliances
    position = {col: i for i, col in enumerate(order)}
    A = np.zeros((sum(len(a) for a, _ in pieces), len(order)))
    r = 0
    for a, targets in pieces:
        for c, col in targets:
            A[r:r + len(a), position[col]] = a[:, c]
        r += len(a)
    return A, [info[col] for col in order], used_ks, len(configurations)


def prior_sigma(desc, name: str, index: int | None, axis: int) -> float:
    sigma = desc.parameters[name].sigma
    return float(sigma[index or 0][axis]) if sigma is not None else np.inf


MAX_PARTNERS = 4  # parameters named in a held element's reason; more are counted


def held_reason(result, held: list[int], names: list[str]) -> str:
    """Why the columns `held` (the axes of one variable) are held, in the words the summary prints after
    `held`: "not identifiable with base.rz" -- the other parameters of their combinations, each once."""
    partners = list(dict.fromkeys(names[j] for h in held for j, _ in result.combinations[h]))
    if not partners:
        return "moves no measurement"
    more = len(partners) - MAX_PARTNERS
    shown = ", ".join(partners[:MAX_PARTNERS]) + (f" and {more} more" if more > 0 else "")
    return f"not identifiable with {shown}"


def _hold(ctx, robot: str, desc, info: list, result, names: list[str], used_ks: dict) -> None:
    """A hold factor on the held axes of each variable, and ctx.hold so that reports print them as held."""
    by_variable: dict[tuple, list[int]] = {}
    for h in result.held:
        _, name, index, _, _, _ = info[h]
        by_variable.setdefault((name, index), []).append(h)
    for (name, index), columns in by_variable.items():
        param = desc.parameters[name]
        value = param.values[index or 0]
        vartype = param.vartype.name if param.vartype.name in ("pose3", "scalar") else "vector"
        label = f"held:{robot}/{element_name(desc, name, index)}"
        axes = [info[h][3] for h in columns]
        axis_labels = [info[h][4].lstrip(".") for h in columns] if vartype != "scalar" else []
        reason = held_reason(result, columns, names)
        ks = sorted(used_ks[(name, index)]) if param.time_varying else [None]
        for k in ks:
            key = ctx.parameter(robot, name, index, k)
            ctx.add_constraint(hold_factor(key, vartype, value, sorted(axes)), label,
                           float("-inf") if k is None else ctx.state_time(robot, k))
            ctx.hold(key, axes, reason, axis_labels)


def _terms(result, h: int, names: list[str], info: list) -> str:
    unit_h = info[h][5]
    parts = []
    for j, c in result.combinations[h][:4]:
        per = "" if info[j][5] == unit_h else f" {info[j][5]}/{unit_h} x"
        parts.append(f"{names[j]} by {c:+.3g}{per} d")
    more = len(result.combinations[h]) - 4
    return ", ".join(parts) + (f" (and {more} more)" if more > 0 else "")


def verdict(result, names: list[str], info: list, scale: np.ndarray, configurations: int) -> list[str]:
    """The diagnostic in sentences: the count, each held parameter with its combination, the weak ones."""
    n = len(names)
    if result.identifiable:
        lines = [f"all {n} kinematic parameters are identifiable from {configurations} configurations "
                 f"(condition {result.condition:.1e})"]
    else:
        lines = [f"{n - result.rank} of {n} kinematic parameters are not identifiable from these {configurations} "
                 f"configurations and are held at their nominal values; the other {result.rank} are estimated "
                 f"(condition {result.condition:.1e})"]
    for h in result.held:
        terms = _terms(result, h, names, info)
        lines.append(f"{names[h]}: not identifiable: changing it by d and {terms} leaves every measurement "
                     "unchanged; held" if terms else f"{names[h]}: moves no measurement; held")
    for j in range(n):
        if j not in result.held and np.isfinite(scale[j]) and result.sigma[j] > scale[j]:
            unit = info[j][5]
            lines.append(f"{names[j]}: weakly identified: the data alone give +-{result.sigma[j]:.2g} {unit}, more "
                         f"than its prior +-{scale[j]:.2g} {unit}; the estimate leans on the prior")
    return lines
