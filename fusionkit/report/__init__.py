"""Outputs of a run: report.json, calibration.yaml, trajectories, plots, the stdout summary."""
