"""fusionkit's public plugin API: everything a plugin, built-in or third-party, may import.

    from fusionkit.api import FactorType, Spec, hookimpl, POSE3, gaussian, ...

Plugins import from this module (and `fusionkit.testing` in their tests) only; the rest of
`fusionkit` is internal and may change. `API_VERSION` follows semantic versioning: a minor
version adds names, a major one changes or removes them. docs/plugin_guide.md documents each name.
"""

from __future__ import annotations

from . import lie, se2
from .hookspecs import hookimpl
from .components import (CheckScope, Command, FactorType, Initializer, ResidualPart, RobotModel, Simulator, Source,
                         SourceOutput, Spec, pose_parts)
from .data.files import read_csv_stream, read_tum
from .design import Choice, compared_with_random, d_optimal, information, prior_information
from .config.fragments import GRAVITY, NAME_SCHEMA, NON_NEGATIVE_SCHEMA, POSITIVE_SCHEMA
from .data.association import TOLERANCE_SCHEMA, Association, interpolate_poses, nearest, segment_ids
from .data.stream import PLANAR_POSE_COLUMNS, POSE_COLUMNS, Stream, pose_array_from, pose_stream, poses_from_array
from .errors import ConfigError, DataError, FusionkitError, PluginError, SolverError
from .geometry import body_point_range, fit_range_origin, range_factor
from .graph.noise import POSE_SIGMA_SCHEMA, gaussian, pose_sigma_schema, pose_sigmas
from .graph.context import BuildContext
from .graph.passes import pass_token
from .graph.vectorized import VectorizedResidual, instance_factor as vectorized_factor
from .graph.variables import (IMU_BIAS, POINT2, POINT3, POSE2, POSE3, ROT3, SCALAR, VELOCITY3, VarType,
                              vector_type)
from .models.integration import held_intervals
from .models.cable_robot import CableRobot, cable_robot
from .models.cable_statics import cable_pull_wrenches, weight_wrench
from .models.pulley import pulley_cables
from .models.odometry import odometry_pairs, sensor_mount, stream_poses_at
from .models.planar import arc_path, differential_drive_twist, unicycle_increment
from .descriptions.description import Parameter, RobotDescription, Sensor
from .descriptions.checked import load_robot_description
from .descriptions.registered import robot_description_data, robot_description_files
from .report.writer import check_output_folder, write_output_folder
from .models.simulation import (CLOCK_SCHEMA, POSE_NOISE_SCHEMA, clock_times, noisy, odometry, sample_times,
                                smooth_trajectory)
from .solve.identifiability import parameter_indices
from .testing import FactorExample
from .view.shapes import Lines, Points

API_VERSION = "1.14"  # 1.1: TOLERANCE_SCHEMA, ctx.associate(stream, robot, spec), schema defaults applied at load
# 1.2: RobotModel.outputs, Command (hook register_commands), load_robot_description, read_csv_stream,
#      check_output_folder, write_output_folder
# 1.3: `time_offset:` on entries that associate by stamp (measurement-time indices), ctx.state_index,
#      CLOCK_SCHEMA and clock_times (simulated clock drift)
# 1.4: FactorType.review(ctx, spec, values) after solving; streams may repeat stamps (a component's
#      accepts_repeated_stamps: the stream fields it takes sample by sample)
# 1.5: vectorized factors: VectorizedResidual, ctx.add_vectorized, vectorized_factor (one instance, for
#      examples), lie (SE(3) for N poses at once)
# 1.6: RobotModel.geometry (what `fusionkit view` draws of a robot) with the shapes Points and Lines
# 1.7: `noise_scale:` on every factor entry (ctx.noise applies it); ctx.add(..., part=) for a factor whose
#      noise is the plugin's own (neither the entry's kernel nor its scale applies)
# 1.8: se2 (SE(2) for N planar poses at once, as lie for SE(3))
# 1.9: FactorType.separation_hint(spec, parameters) for the identifiability report, parameter_indices,
#      RobotModel.axis_names (a vector parameter's component names)
# 1.10: FactorType.residual_parts(ctx, spec) with ResidualPart: the named parts of a residual that
#      `fusionkit crossval` reports held-out errors of, pose_parts (a pose residual's position and orientation);
#      experiment design: d_optimal, Choice, information, prior_information, compared_with_random;
#      ctx.add_diagnostic(..., identifiability=True): a family's analysis joins the identifiability report
# 1.11: pass_token(values): fusionkit's evaluator is costing or linearizing this very Values object (factors
#      with many variables that share one evaluation read them once per pass)
# 1.12: BuildContext, the protocol of the `ctx` a plugin receives (ctx.family, robot_of, initial_values, entries,
#      factors, note, add_constraint added); plugins declare the API they are written for (FUSIONKIT_API);
#      NAME_SCHEMA, POSITIVE_SCHEMA, NON_NEGATIVE_SCHEMA, GRAVITY (one definition for every family); arc_path;
#      the `cdpr` robot model is the core's, read through CableRobot / cable_robot by every cable family
# 1.13: variable types are plugins (hook register_variable_types): VarType carries its names, units, array form,
#      retraction and interpolation; `between` may be None; odometry_pairs, sensor_mount, stream_poses_at (a pose
#      stream against a robot's states, shared by the pose and imu families); the ctx plugins receive has the
#      BuildContext operations only (anything else: AttributeError)
# 1.14: ctx.sigma(key): after solving (FactorType.review), a variable's 1-sigma per tangent axis; pulley_cables
#      (a cable over a swivelling pulley, the core's cable model), cable_pull_wrenches and weight_wrench (its statics); load_robot_description(..., calibration=, robot=); read_tum

__all__ = [
    "API_VERSION", "hookimpl",
    # components a plugin provides, and what they are given
    "CheckScope", "FactorType", "ResidualPart", "pose_parts", "Initializer", "RobotModel", "Simulator", "Source",
    "SourceOutput", "Spec",
    "RobotDescription", "Parameter", "Sensor",
    # robot descriptions shipped as package data, by name; a description by name or file, checked
    "robot_description_files", "robot_description_data", "load_robot_description",
    # subcommands of `fusionkit`, and the output folders they (and robot models' outputs) write
    "Command", "check_output_folder", "write_output_folder", "read_csv_stream", "read_tum",
    # experiment design (D-optimal choice of candidate measurements)
    "d_optimal", "Choice", "information", "prior_information", "compared_with_random",
    # errors (one located line each)
    "ConfigError", "DataError", "FusionkitError", "PluginError", "SolverError",
    # variables and noise
    "VarType", "vector_type", "POSE3", "POSE2", "POINT3", "POINT2", "ROT3", "SCALAR", "VELOCITY3", "IMU_BIAS",
    "gaussian", "pose_sigmas", "pose_sigma_schema", "POSE_SIGMA_SCHEMA",
    # streams and association with states
    "Stream", "POSE_COLUMNS", "PLANAR_POSE_COLUMNS", "pose_stream", "pose_array_from", "poses_from_array",
    "Association", "nearest", "TOLERANCE_SCHEMA", "interpolate_poses", "segment_ids",
    # schema fragments and the standard gravity every family shares
    "NAME_SCHEMA", "POSITIVE_SCHEMA", "NON_NEGATIVE_SCHEMA", "GRAVITY",
    # the cable robot description every cable family reads (model `cdpr`)
    "CableRobot", "cable_robot", "pulley_cables", "cable_pull_wrenches", "weight_wrench",
    # shared models
    "body_point_range", "fit_range_origin", "range_factor", "held_intervals", "unicycle_increment", "arc_path",
    "differential_drive_twist", "odometry_pairs", "sensor_mount", "stream_poses_at",
    # simulator building blocks and the factor contract
    "POSE_NOISE_SCHEMA", "noisy", "odometry", "sample_times", "smooth_trajectory", "FactorExample",
    "CLOCK_SCHEMA", "clock_times",
    # factors evaluated many at a time (ctx.add_vectorized) and the SE(3) and SE(2) arrays they are written with
    "VectorizedResidual", "vectorized_factor", "lie", "se2",
    # CustomFactors sharing one evaluation: the pass of fusionkit's evaluator they are called in
    "pass_token",
    # what the `ctx` of build / diagnose / initialize offers
    "BuildContext",
    # what a robot model draws of itself (RobotModel.geometry)
    "Points", "Lines",
    # FactorType.separation_hint: which elements of a parameter a group names
    "parameter_indices",
]
