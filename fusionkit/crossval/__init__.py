"""`fusionkit crossval`: held-out prediction errors of a config's calibration (folds.py, predict.py, scores.py,
run.py, command.py; docs/models/unified_graph.md#held-out-prediction-fusionkit-crossval)."""
