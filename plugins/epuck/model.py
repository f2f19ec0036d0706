"""Robot models of the e-puck plugin (docs/reference/robot_description.md#model-epuck):

`epuck`: a differential-drive robot with IR proximity sensors, each with its own sensor model --

    model: epuck
    wheel_radius: 0.0205            # m
    axle_length: 0.053              # m
    ir_range: [0.005, 0.07]         # m: the distances the sensor models were fitted on
    ir_distance_unit: 0.01          # m per unit of x in the Gaussian sums (the published fits: cm)
    velocity_noise: {alpha: [0.045, 8.8e-5, 0.095862, 0.1181]}   # SI: -, m/rad, rad/m, - (+ alpha5, alpha6)
    sensors:
      ir0:
        type: ir_proximity
        mount: {translation: [0.030, -0.010, 0.033], rotation_rpy: [0, 0, -0.3007]}   # the axis: yaw
        mean: [[a, b, c], ...]      # mean reading (counts) = sum a exp(-((x - b) / c)^2)
        variance: [[a, b, c], ...]  # its variance (counts^2), the same form
        dropout: 0.02               # optional: probability of a reading of 0 whatever the distance
        saturation: 4095            # optional: the reading it clips at (readings there are censored: "at least")

`wall_map`: a known map, walls as segments and closed polygons (m) --

    model: wall_map
    segments: [[[x0, y0], [x1, y1]], ...]
    polygons: [[[x, y], [x, y], [x, y], ...], ...]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusionkit.api import Lines, POSITIVE_SCHEMA as POSITIVE, RobotDescription, RobotModel, robot_description_data

from .irmodel import Bank
from .walls import segments_of

IR_TYPE = "ir_proximity"
POINT = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}


@dataclass
class IrLayout:
    """The IR sensors of an epuck description: names, mounts (S, 2) m, axis angles (S,) rad, models."""

    names: list[str]
    mounts: np.ndarray
    angles: np.ndarray
    bank: Bank


def ir_layout_from_data(data: dict, names: list[str] | None = None) -> IrLayout:
    """The IR sensors of a description mapping (a shipped description's data, for simulators)."""
    sensors = {n: s for n, s in (data.get("sensors") or {}).items() if s.get("type") == IR_TYPE}
    names = list(names or sensors)
    mounts = np.array([sensors[n].get("mount", {}).get("translation", [0.0, 0.0, 0.0])[:2] for n in names], float)
    angles = np.array([sensors[n].get("mount", {}).get("rotation_rpy", [0.0, 0.0, 0.0])[2] for n in names], float)
    lo, hi = data["ir_range"]
    bank = Bank([sensors[n]["mean"] for n in names], [sensors[n]["variance"] for n in names],
                data["ir_distance_unit"], lo, hi, [sensors[n].get("dropout", 0.0) for n in names],
                [sensors[n].get("saturation") for n in names])
    return IrLayout(names, mounts.reshape(-1, 2), angles, bank)


def shipped_layout(name: str = "epuck") -> IrLayout:
    """The IR sensors of a shipped epuck description (default: the e-puck's published models)."""
    return ir_layout_from_data(robot_description_data(name))


def ir_layout(desc: RobotDescription, names: list[str] | None = None) -> IrLayout:
    """The IR sensors of a loaded epuck description (all of them, or `names` in that order)."""
    names = list(names or ir_sensor_names(desc))
    sensors = [desc.sensors[n] for n in names]
    mounts = np.array([np.asarray(s.mount.translation())[:2] for s in sensors], float).reshape(-1, 2)
    angles = np.array([s.mount.rotation().yaw() for s in sensors], float)
    lo, hi = desc.extra["ir_range"]
    bank = Bank([s.extra["mean"] for s in sensors], [s.extra["variance"] for s in sensors],
                desc.extra["ir_distance_unit"], lo, hi, [s.extra.get("dropout", 0.0) for s in sensors],
                [s.extra.get("saturation") for s in sensors])
    return IrLayout(names, mounts, angles, bank)


def ir_sensor_names(desc: RobotDescription) -> list[str]:
    return [n for n, s in desc.sensors.items() if s.type == IR_TYPE]


def alphas(extra: dict) -> np.ndarray:
    """The description's velocity-noise alphas (4 or 6, SI)."""
    return np.asarray(extra["velocity_noise"]["alpha"], float)


class EpuckModel(RobotModel):
    name = "epuck"
    summary = ("e-puck: differential drive (wheel radius, axle), IR proximity sensors each with a Gaussian-sum "
               "model of its mean reading and variance, velocity-model noise alpha1-4 (5-6)")
    schema = {"type": "object",
              "properties": {"wheel_radius": POSITIVE, "axle_length": POSITIVE,
                             "ir_range": {"type": "array", "items": {"type": "number", "minimum": 0},
                                          "minItems": 2, "maxItems": 2},
                             "ir_distance_unit": POSITIVE,
                             "velocity_noise": {"type": "object",
                                                "properties": {"alpha": {"type": "array",
                                                                         "items": {"type": "number", "minimum": 0},
                                                                         "minItems": 4, "maxItems": 6}},
                                                "required": ["alpha"], "additionalProperties": False}},
              "required": ["wheel_radius", "axle_length", "ir_range", "ir_distance_unit", "velocity_noise"],
              "additionalProperties": False}

    def check_description(self, desc: RobotDescription) -> None:
        """ir_range increasing; 4 or 6 alphas; every ir_proximity sensor has `mean` and `variance`
        lists of (a, b, c) terms with c != 0, only those keys besides its mount, and a variance that
        is positive over ir_range."""
        lo, hi = desc.extra["ir_range"]
        if lo >= hi:
            raise desc.error(("ir_range",), f"[{lo}, {hi}]: expected [d_min, d_max] with d_min < d_max (m)")
        if len(desc.extra["velocity_noise"]["alpha"]) == 5:
            raise desc.error(("velocity_noise", "alpha"), "5 values: expected alpha1-4, or alpha1-6")
        for name in ir_sensor_names(desc):
            self._check_sensor(desc, name)
        if ir_sensor_names(desc):
            layout = ir_layout(desc)
            bad = np.flatnonzero(layout.bank.grid_var.min(axis=0) <= 0)
            if len(bad):
                s = bad[0]
                d = layout.bank.grid[np.argmin(layout.bank.grid_var[:, s])]
                raise desc.error(("sensors", layout.names[s], "variance"), f"the variance model is not positive "
                                 f"at d = {d:.4g} m, inside ir_range; a variance must be > 0 over the range")

    @staticmethod
    def _check_sensor(desc: RobotDescription, name: str) -> None:
        extra = desc.sensors[name].extra
        path = ("sensors", name)
        unknown = sorted(set(extra) - {"mean", "variance", "dropout", "saturation"})
        if unknown:
            raise desc.error(path + (unknown[0],), f"unknown key for an {IR_TYPE} sensor; accepted: type, frame, "
                             "mount, mean, variance, dropout, saturation")
        top = extra.get("saturation", 1.0)
        if isinstance(top, bool) or not isinstance(top, (int, float)) or not top > 0:
            raise desc.error(path + ("saturation",), f"{top!r}: expected the reading (counts, > 0) the sensor clips at")
        p = extra.get("dropout", 0.0)
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0.0 <= p < 1.0:
            raise desc.error(path + ("dropout",), f"{p!r}: expected a probability in [0, 1) (the fraction of readings "
                             "that fall to 0 whatever the distance)")
        for key in ("mean", "variance"):
            if key not in extra:
                raise desc.error(path, f"an {IR_TYPE} sensor needs `{key}:` (Gaussian-sum terms [[a, b, c], ...])")
            terms = extra[key]
            if not isinstance(terms, list) or not terms:
                raise desc.error(path + (key,), "expected a list of terms [a, b, c]")
            for i, term in enumerate(terms):
                ok = isinstance(term, list) and len(term) == 3 and all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in term)
                if not ok:
                    raise desc.error(path + (key, i), f"{term!r}: expected a term [a, b, c] of three finite numbers")
                if term[2] == 0:
                    raise desc.error(path + (key, i, 2), "c = 0: a term's width must not be zero")


class WallMapModel(RobotModel):
    name = "wall_map"
    summary = "a known planar map: walls as segments and closed polygons (m); no states, no parameters"
    schema = {"type": "object",
              "properties": {"segments": {"type": "array", "items": {"type": "array", "items": POINT,
                                                                     "minItems": 2, "maxItems": 2}},
                             "polygons": {"type": "array", "items": {"type": "array", "items": POINT,
                                                                     "minItems": 3}}},
              "additionalProperties": False}

    def geometry(self, robot: str, calibrated: RobotDescription, state: dict) -> list:
        """The walls, on the floor (z = 0)."""
        walls = walls_of(calibrated)
        return [Lines(f"{robot} walls", np.concatenate([walls, np.zeros(walls.shape[:2] + (1,))], axis=2),
                      "#7f7f7f", 2.0)]

    def check_description(self, desc: RobotDescription) -> None:
        """At least one wall; no segment (or polygon edge) of zero length."""
        segments, polygons = desc.extra.get("segments", []), desc.extra.get("polygons", [])
        if not segments and not polygons:
            raise desc.error(("model",), "a wall_map needs walls: `segments:` and/or `polygons:`")
        for i, seg in enumerate(segments):
            if np.allclose(seg[0], seg[1]):
                raise desc.error(("segments", i), f"{seg}: a segment of zero length")
        for i, poly in enumerate(polygons):
            p = np.asarray(poly, float)
            if np.any(np.all(np.isclose(p, np.roll(p, -1, axis=0)), axis=1)):
                raise desc.error(("polygons", i), "two consecutive vertices coincide (an edge of zero length)")


def walls_of(desc: RobotDescription) -> np.ndarray:
    """(M, 2, 2) wall segments of a wall_map description."""
    return segments_of(desc.extra.get("segments", []), desc.extra.get("polygons", []))


def walls_from_data(data: dict) -> np.ndarray:
    return segments_of(data.get("segments", []), data.get("polygons", []))
