"""A recorded robot's ROS bag used as it is: wheel angles from a sensor_msgs/JointState topic (joints named in
the diff_drive description) and the gyro from a sensor_msgs/Imu topic at its own rate, integrated over each
state interval by the trapezoid rule. A ROS 1 and a ROS 2 bag written from a wheels.sim run give the same
estimates as the same numbers in CSV files; an absent joint or streams that do not overlap are one located
error line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from fusionkit import load_config
from fusionkit.api import robot_description_data
from fusionkit.cli.main import main
from fusionkit.pipeline import estimate, read_sources
from fusionkit.simulate import simulated_config
from fusionkit_plugins.wheels.kinematics import trapezoid_increments

JOINTS = {"left": "wheel_left_joint", "right": "wheel_right_joint", "passive": "caster_joint"}
JOINT_TYPE, IMU_TYPE = "sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu"
T0 = 1_700_000_000.0   # epoch-sized stamps, as a recording has
IMU_RATE = 50.0        # Hz: the IMU runs at its own rate and phase, not the wheels' 20 Hz


def stamps(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sec, nanosec, the float time a reader makes of them)."""
    ns = np.round(np.asarray(t) * 1e9).astype(np.int64)
    sec, nsec = ns // 10**9, ns % 10**9
    return sec, nsec, sec + nsec * 1e-9


@pytest.fixture(scope="module")
def recording() -> dict:
    """3 s of wheels.sim (wheel angles in rad) on bag stamps, and a 50 Hz IMU sampling the simulated gyro."""
    with simulated_config("wheels.sim", {"duration": 3.0, "path": "slalom"}, seed=4) as config:
        streams, _ = read_sources(config)
    desc = robot_description_data("passive_wheel_robot")
    wheels = streams["wheels"]
    _, _, t = stamps(T0 + wheels.t)
    angles = {w: wheels.column(w) * 2 * np.pi / desc[key]
              for w, key in (("left", "ticks_per_revolution"), ("right", "ticks_per_revolution"),
                             ("passive", "passive_ticks_per_revolution"))}
    _, _, imu_t = stamps(np.arange(t[0] + 0.013, t[-1], 1.0 / IMU_RATE))
    middle = 0.5 * (t[1:] + t[:-1])  # the simulated gyro sample is the mean rate over the interval ending at t_i
    gz = np.interp(imu_t, middle, wheels.column("gyro")[1:])
    del desc["ticks_per_revolution"], desc["passive_ticks_per_revolution"]
    return {"t": t, "angles": angles, "imu_t": imu_t, "gz": gz, "description": desc}


def write_csv(path: Path, t: np.ndarray, columns: dict) -> None:
    """Full precision (the reader's floats exactly), unlike the 9 digits of fusionkit's own CSV writer."""
    np.savetxt(path, np.column_stack([t, *columns.values()]), delimiter=",", fmt="%.17g",
               header="t," + ",".join(columns), comments="")


def write_bag(path: Path, ros: int, rec: dict, joints: dict = JOINTS) -> Path:
    ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    T = ts.types
    seq = {"seq": 0} if "seq" in T["std_msgs/msg/Header"].__dataclass_fields__ else {}

    def header(sec, nsec):
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(nsec)),
                                        frame_id="base_link", **seq)

    def vec(x, y, z):
        return T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    names = list(joints.values())
    positions = np.column_stack([rec["angles"][w] for w in joints])
    messages = [(sec * 10**9 + nsec, "/joint_states", JOINT_TYPE,
                 T[JOINT_TYPE](header=header(sec, nsec), name=names, position=p.copy(),
                               velocity=np.zeros(0), effort=np.zeros(0)))
                for sec, nsec, p in zip(*stamps(rec["t"])[:2], positions)]
    messages += [(sec * 10**9 + nsec, "/imu", IMU_TYPE,
                  T[IMU_TYPE](header=header(sec, nsec), orientation=T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                              orientation_covariance=np.zeros(9), angular_velocity=vec(0.001, -0.002, g),
                              angular_velocity_covariance=np.zeros(9), linear_acceleration=vec(0.0, 0.0, 9.81),
                              linear_acceleration_covariance=np.zeros(9)))
                 for sec, nsec, g in zip(*stamps(rec["imu_t"])[:2], rec["gz"])]
    serialize = ts.serialize_ros1 if ros == 1 else ts.serialize_cdr
    with (Writer1(path) if ros == 1 else Writer2(path, version=9)) as w:
        conns = {topic: w.add_connection(topic, typ, typestore=ts) for topic, typ in
                 (("/joint_states", JOINT_TYPE), ("/imu", IMU_TYPE))}
        for stamp, topic, typ, msg in sorted(messages, key=lambda m: m[0]):
            w.write(conns[topic], int(stamp), serialize(msg, typ))
    return path


def config(sources: list, description: dict) -> dict:
    """The wheels.sim graph (per-wheel encoders, gyro, no sideways motion, dead reckoning), gyro from `imu`."""
    return {"name": "bag_wheels", "sources": sources,
            "robots": {"robot": {"description": description, "states": {"stream": "wheels", "type": "pose2"}}},
            "factors": [{"type": "pose.origin", "robot": "robot", "sigma": {"rotation": 1e-4, "translation": 1e-4}},
                        {"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "sigma": 0.006,
                         "over_read": 3.0},
                        {"type": "wheels.gyro", "robot": "robot", "stream": "imu", "sigma": 0.002},
                        {"type": "wheels.nonholonomic", "robot": "robot", "sigma": 1e-3}],
            "initializers": [{"type": "wheels.dead_reckoning", "robot": "robot", "stream": "wheels",
                              "forward": "passive"}],
            "solver": {"type": "batch", "method": "lm"}, "output": {"plots": False}}


def bag_config(path: Path, description: dict) -> dict:
    return config([{"type": "rosbag", "path": path.name, "topics": {"/joint_states": "wheels", "/imu": "imu"}}],
                  {"joints": JOINTS, **description})


def solution(result) -> np.ndarray:
    params = result.parameters["robot"]
    return np.concatenate([result.trajectories["robot"].values.ravel(),
                           [float(params[name].values[0]) for name in sorted(params)]])


def test_ros1_and_ros2_bags_give_the_csv_runs_estimates(workspace, recording):
    """CSV: columns left/right/passive and an IMU CSV (t, gz). Bags: JointState with the joints named in the
    description (in an order of their own), Imu at 50 Hz. Poses and intrinsics agree to 1e-9."""
    rec = recording
    write_csv(workspace.folder / "wheels.csv", rec["t"], rec["angles"])
    write_csv(workspace.folder / "imu.csv", rec["imu_t"], {"gz": rec["gz"]})
    csv = estimate(load_config(workspace.config(config(
        [{"type": "csv", "name": "wheels", "path": "wheels.csv"}, {"type": "csv", "name": "imu", "path": "imu.csv"}],
        rec["description"]))))
    expected = solution(csv)
    assert len(csv.trajectories["robot"].t) == len(rec["t"]) and len(expected) > 3 * len(rec["t"])
    for ros, name in ((1, "run.bag"), (2, "run_ros2")):
        bag = write_bag(workspace.folder / name, ros, rec, dict(reversed(list(JOINTS.items()))))
        result = estimate(load_config(workspace.config(bag_config(bag, rec["description"]), f"bag{ros}.yaml")))
        np.testing.assert_allclose(solution(result), expected, rtol=0, atol=1e-9)
    # the IMU's first and last samples fall inside the first and last state intervals: those two get no gyro factor
    assert result.notes == [f"factors[2]:wheels.gyro: 2 of {len(rec['t']) - 1} state intervals of 'robot' lie outside "
                            f"stream 'imu' and get no factor from it"]


def mean_rates(t: np.ndarray, imu_t: np.ndarray, gz: np.ndarray) -> np.ndarray:
    """The IMU's mean rate over each interval (t_{i-1}, t_i), by numpy's trapezoid over the samples inside and
    the rate interpolated at both ends (written independently of the plugin's cumulative form)."""
    out = []
    for a, b in zip(t[:-1], t[1:]):
        at = np.concatenate([[a], imu_t[(imu_t > a) & (imu_t < b)], [b]])
        out.append(np.trapezoid(np.interp(at, imu_t, gz), at) / (b - a))
    return np.array(out)


def test_baseline_with_the_bags_imu_as_gyro_stream_is_gyrodometry_on_its_mean_rates(workspace, recording):
    """wheels.rule_odometry (gyrodometry) with `gyro_stream: imu` on a ROS 2 bag (IMU covering the wheel stream)
    gives the trajectory of the same rule on a CSV whose gyro column is the IMU's mean rate over each wheel
    interval, to 1e-9."""
    rec = dict(recording)
    rec["imu_t"] = stamps(np.arange(rec["t"][0] - 0.007, rec["t"][-1] + 0.02, 1.0 / IMU_RATE))[2]
    rec["gz"] = np.interp(rec["imu_t"], recording["imu_t"], recording["gz"])
    gyro = np.concatenate([[0.0], mean_rates(rec["t"], rec["imu_t"], rec["gz"])])
    write_csv(workspace.folder / "wheels.csv", rec["t"], {**rec["angles"], "gyro": gyro})
    baseline = {"type": "wheels.rule_odometry", "robot": "robot", "stream": "wheels", "method": "gyrodometry"}
    csv = config([{"type": "csv", "name": "wheels", "path": "wheels.csv"}], rec["description"])
    csv["factors"], csv["initializers"] = [csv["factors"][0], baseline], []
    bag = bag_config(write_bag(workspace.folder / "run_ros2", 2, rec), rec["description"])
    bag["factors"], bag["initializers"] = [bag["factors"][0], {**baseline, "gyro_stream": "imu"}], []
    expected = estimate(load_config(workspace.config(csv))).trajectories["robot"].values
    got = estimate(load_config(workspace.config(bag, "bag.yaml"))).trajectories["robot"].values
    assert len(got) == len(rec["t"]) and np.ptp(expected[:, 0]) > 0.1
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


def test_imu_rate_is_integrated_by_the_trapezoid_rule_over_unaligned_intervals():
    """A rate linear in time is integrated exactly between times that fall between samples (irregular
    samples); a smooth one to the trapezoid rule's accuracy, where the nearest sample's rate is 1000x off."""
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.015, 0.025, 200))
    times = np.sort(rng.uniform(t[0], t[-1], 30))
    got = trapezoid_increments(t, 0.4 - 0.3 * t, times)
    np.testing.assert_allclose(got, 0.4 * np.diff(times) - 0.15 * np.diff(times ** 2), rtol=0, atol=1e-13)
    exact = np.diff(-np.cos(3 * times)) / 3
    trapezoid = trapezoid_increments(t, np.sin(3 * t), times)
    nearest = np.sin(3 * t[np.abs(t[:, None] - times[None, :-1]).argmin(axis=0)]) * np.diff(times)
    assert np.abs(trapezoid - exact).max() < 1e-4
    assert np.abs(trapezoid - exact).max() * 1000 < np.abs(nearest - exact).max()


@pytest.mark.parametrize("case, needle", [
    ("absent joint", "factors[1].stream: robot 'robot' names joint 'caster_joint' for its passive wheel "
                     "(joints.passive); stream 'wheels'"),
    ("imu on another clock", "factors[2]:wheels.gyro: stream 'imu' ("),
    ("passive joint not named", "config.yaml:11: joints: the robot has a passive wheel: name its joint too"),
])
def test_absent_or_unnamed_joint_and_streams_that_do_not_overlap_are_one_located_line(workspace, recording, capsys,
                                                                                        case, needle):
    rec, joints, description = dict(recording), JOINTS, dict(recording["description"])
    if case == "absent joint":
        joints = {**JOINTS, "passive": "caster_wheel_joint"}  # the bag names the joint differently
    elif case == "imu on another clock":
        rec["imu_t"] = rec["imu_t"] - 3600.0  # an IMU stamped an hour early: no state interval inside it
    else:
        description["joints"] = {w: j for w, j in JOINTS.items() if w != "passive"}
    bag = write_bag(workspace.folder / "run.bag", 1, rec, joints)
    path = workspace.config(bag_config(bag, description))
    assert main(["run", str(path), "--out", str(workspace.folder / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert not (workspace.folder / "out").exists()
