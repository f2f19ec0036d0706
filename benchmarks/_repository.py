"""The repository root on sys.path, for a benchmark run as a script (`python benchmarks/bench_x.py`, which puts
only benchmarks/ there): the research code (research/) is imported as `research.<module>`. Import it first."""

import sys
from pathlib import Path

ROOT = str(Path(__file__).resolve().parents[1])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
