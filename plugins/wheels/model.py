"""The `diff_drive` robot model: a differential drive (two driven wheels on one axle), optionally a
passive encoder wheel on the axle and a gyro (docs/reference/robot_description.md#model-diff_drive).

    model: diff_drive
    ticks_per_revolution: 2048          # optional: the left/right columns are encoder ticks (else rad)
    passive_ticks_per_revolution: 1024  # optional: the passive column is ticks (else rad)
    joints: {left: wheel_left_joint, right: wheel_right_joint, passive: caster_joint}  # optional: column names
    parameters:                          # scalars with a value; names fixed by the model
      wheel_radius_left:  {type: scalar, value: 0.04, sigma: 0.0005, unit: m}     # required
      wheel_radius_right: {type: scalar, value: 0.04, sigma: 0.0005, unit: m}     # required
      axle_length:        {type: scalar, value: 0.25, sigma: 0.002, unit: m}      # required
      passive_radius:     {type: scalar, value: 0.025, sigma: 0.0005, unit: m}    # the robot has a passive wheel
      passive_offset:     {type: scalar, value: 0.0, fixed: true, unit: m}        # its position on the axle
      gyro_scale:         {type: scalar, value: 1.0, sigma: 0.3}                  # the robot has a gyro:
      gyro_bias:          {type: scalar, value: 0.0, sigma: 0.1, unit: rad/s}     #   true rate = scale * reading + bias

The robot's pose is the axle midpoint, x forward, y towards the left wheel; `passive_offset` is the
passive wheel's lateral position (m, towards the left wheel; absent: the midpoint). Any of the
parameters may be `time_varying` (a drifting radius, a drifting gyro bias). `joints` names the wheel
stream's column of each wheel -- the robot's joint names, as a ROS JointState topic gives them; absent,
the columns are `left`, `right`, `passive`.
"""

from __future__ import annotations

from dataclasses import dataclass

from fusionkit.api import RobotDescription, RobotModel

RADIUS_LEFT, RADIUS_RIGHT, AXLE = "wheel_radius_left", "wheel_radius_right", "axle_length"
PASSIVE_RADIUS, PASSIVE_OFFSET = "passive_radius", "passive_offset"
GYRO_SCALE, GYRO_BIAS = "gyro_scale", "gyro_bias"
RADIUS = {"left": RADIUS_LEFT, "right": RADIUS_RIGHT, "passive": PASSIVE_RADIUS}
POSITIVE = (RADIUS_LEFT, RADIUS_RIGHT, AXLE, PASSIVE_RADIUS)
NAMES = POSITIVE + (PASSIVE_OFFSET, GYRO_SCALE, GYRO_BIAS)
TICKS = {"type": "number", "exclusiveMinimum": 0}
JOINT = {"type": "string", "minLength": 1}
JOINTS = {"type": "object", "properties": {"left": JOINT, "right": JOINT, "passive": JOINT},
          "required": ["left", "right"], "additionalProperties": False}


@dataclass(frozen=True)
class DiffDrive:
    """A checked diff_drive description: which wheels and sensors it has, its encoder resolution and
    the nominal value of each of its parameters."""

    nominal: dict[str, float]
    ticks: dict[str, float | None]   # wheel -> ticks per revolution (None: the column is in rad)
    columns: dict[str, str]          # wheel -> its column in the wheel stream (a joint name, or the wheel's)

    @property
    def has_passive(self) -> bool:
        return PASSIVE_RADIUS in self.nominal

    @property
    def has_gyro(self) -> bool:
        return GYRO_BIAS in self.nominal

    @property
    def wheels(self) -> tuple[str, ...]:
        return ("left", "right", "passive") if self.has_passive else ("left", "right")

    @property
    def passive_offset(self) -> float:
        """Nominal lateral position of the passive wheel (m, towards the left wheel; 0 when not a parameter)."""
        return self.nominal.get(PASSIVE_OFFSET, 0.0)


def drive_of(desc: RobotDescription) -> DiffDrive:
    """The DiffDrive of a (checked) diff_drive description."""
    nominal = {name: float(desc.parameters[name].values[0]) for name in NAMES if name in desc.parameters}
    ticks = desc.extra.get("ticks_per_revolution")
    columns = {wheel: wheel for wheel in ("left", "right", "passive")}
    columns.update(desc.extra.get("joints", {}))
    return DiffDrive(nominal, {"left": ticks, "right": ticks,
                               "passive": desc.extra.get("passive_ticks_per_revolution")}, columns)


class DiffDriveModel(RobotModel):
    name = "diff_drive"
    summary = ("differential drive: wheel radii, axle length, optional passive wheel on the axle (radius, "
               "offset) and gyro (scale, bias); encoder ticks or wheel angles")
    schema = {"type": "object",
              "properties": {"ticks_per_revolution": TICKS, "passive_ticks_per_revolution": TICKS,
                             "joints": JOINTS},
              "additionalProperties": False}

    def check_description(self, desc: RobotDescription) -> None:
        """The driven wheels' parameters exist; every parameter the model names is one scalar with a
        value (radii and axle length > 0); a passive offset or passive ticks need the passive wheel,
        which must lie between the driven wheels; the gyro has both its scale and its bias; `joints` names
        the passive wheel's joint exactly when there is one, and three different joints."""
        params = desc.parameters
        for name in (RADIUS_LEFT, RADIUS_RIGHT, AXLE):
            if name not in params:
                raise desc.error(("parameters",), f"a diff_drive robot needs parameter {name!r} (a scalar, m); "
                                 f"the description has: {', '.join(params) or '(none)'}")
        for name in NAMES:
            p = params.get(name)
            if p is None:
                continue
            if p.vartype.name != "scalar" or p.indexed:
                raise desc.error(("parameters", name), f"{name} must be one scalar (`type: scalar`, `value:`); "
                                 f"it is {p.count} {p.vartype.name}")
            if not p.known:
                raise desc.error(("parameters", name), f"{name} needs its nominal value: give `value:`")
            if name in POSITIVE and float(p.values[0]) <= 0:
                raise desc.error(("parameters", name, "value"), f"{name} must be > 0 m; got {p.values[0]}")
        passive = PASSIVE_RADIUS in params
        if "passive_ticks_per_revolution" in desc.extra and not passive:
            raise desc.error(("passive_ticks_per_revolution",), "passive_ticks_per_revolution needs a passive "
                             f"wheel: add parameter {PASSIVE_RADIUS!r}")
        if PASSIVE_OFFSET in params:
            if not passive:
                raise desc.error(("parameters", PASSIVE_OFFSET), f"{PASSIVE_OFFSET} needs a passive wheel: add "
                                 f"parameter {PASSIVE_RADIUS!r}")
            half = 0.5 * float(params[AXLE].values[0])
            if abs(float(params[PASSIVE_OFFSET].values[0])) >= half:
                raise desc.error(("parameters", PASSIVE_OFFSET, "value"), f"the passive wheel must lie between "
                                 f"the driven wheels: |{PASSIVE_OFFSET}| < axle_length / 2 = {half:g} m")
        joints = desc.extra.get("joints")
        if joints is not None:
            if "passive" in joints and not passive:
                raise desc.error(("joints", "passive"), "joints.passive needs a passive wheel: add parameter "
                                 f"{PASSIVE_RADIUS!r}")
            if passive and "passive" not in joints:
                raise desc.error(("joints",), "the robot has a passive wheel: name its joint too (joints.passive)")
            if len(set(joints.values())) < len(joints):
                raise desc.error(("joints",), f"each wheel needs its own joint; got {joints}")
        gyro = [n for n in (GYRO_SCALE, GYRO_BIAS) if n in params]
        if len(gyro) == 1:
            other = GYRO_BIAS if gyro[0] == GYRO_SCALE else GYRO_SCALE
            raise desc.error(("parameters", gyro[0]), f"a gyro needs both {GYRO_SCALE} and {GYRO_BIAS}; "
                             f"add {other!r} (`fixed: true` holds it at its value)")
