"""Do the shipped configs give the same results with the code at another commit? For refactors that must not
change a figure (issue 35: every result of the shipped configs within 1e-12 before and after).

    python benchmarks/same_results.py BASE_COMMIT [--only quickstart arm_calibration ...] [--tolerance 1e-12]

Runs every config in configs/ twice, `fusionkit run --no-plots`, once with the code of BASE_COMMIT (checked out
into a temporary git worktree, imported ahead of the installed package) and once with the working tree, and
compares every number of the two report.json files (estimates, sigmas, evaluation, solver costs; timings and the
seconds of anything left out). Prints per config the largest relative difference, or why it could not run (a
config whose external recording is absent fails alike at both); exit code 1 when a difference exceeds the
tolerance (relative; absolute for numbers below 1) or one side runs where the other fails.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TIMING = ("time", "seconds", "latency", "_s", "elapsed")  # keys whose numbers are wall-clock, not results
RUN = ("import sys; from fusionkit.cli.main import main; "
       "sys.exit(main(['run', sys.argv[1], '--out', sys.argv[2], '-q', '--no-plots']))")


def numbers(report, path: str = "") -> dict[str, float]:
    """Every number of a report.json, by its key path, leaving out timings."""
    out: dict[str, float] = {}
    if isinstance(report, dict):
        for key, value in report.items():
            if not any(word in str(key) for word in TIMING):
                out.update(numbers(value, f"{path}.{key}"))
    elif isinstance(report, list):
        for i, value in enumerate(report):
            out.update(numbers(value, f"{path}[{i}]"))
    elif isinstance(report, (int, float)) and not isinstance(report, bool):
        out[path] = float(report)
    return out


def code_tree(commit: str, folder: Path) -> Path:
    """A folder to put ahead on sys.path so that `fusionkit` and `fusionkit_plugins` import from `commit`."""
    tree = folder / "tree"
    subprocess.run(["git", "worktree", "add", "--detach", str(tree), commit], cwd=REPO, check=True,
                   capture_output=True)
    path = folder / "path"
    path.mkdir()
    (path / "fusionkit").symlink_to(tree / "fusionkit")
    (path / "fusionkit_plugins").symlink_to(tree / "plugins")
    return path


def run(config: Path, out: Path, path: Path | None) -> tuple[dict[str, float] | None, str]:
    """(the numbers of its report.json, or None and the error line) of one run."""
    env = dict(os.environ, MPLBACKEND="Agg")
    if path is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(path)] + [p for p in [env.get("PYTHONPATH")] if p])
    proc = subprocess.run([sys.executable, "-c", RUN, str(config), str(out)], cwd=config.parent, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        return None, (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
    return numbers(json.loads((out / "report.json").read_text())), ""


def largest_difference(a: dict[str, float], b: dict[str, float]) -> tuple[float, str]:
    """(largest difference, where) of two reports' numbers, relative to the larger of the two or to 1 when both are
    below 1; inf where their key paths differ."""
    if a.keys() != b.keys():
        only = sorted(a.keys() ^ b.keys())
        return math.inf, f"numbers only on one side: {', '.join(only[:3])}{' ...' if len(only) > 3 else ''}"
    worst, where = 0.0, ""
    for key, x in a.items():
        y = b[key]
        if math.isnan(x) and math.isnan(y) or x == y:
            continue
        d = abs(x - y) / max(abs(x), abs(y), 1.0)  # relative, absolute below 1 (a bias near 0 is not 100 % off)
        if d > worst:
            worst, where = d, f"{key}: {x!r} vs {y!r}"
    return worst, where


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", help="the commit to compare the working tree with")
    parser.add_argument("--only", nargs="+", help="config names (without .yaml)")
    parser.add_argument("--tolerance", type=float, default=1e-12, help="largest relative difference allowed")
    args = parser.parse_args(argv)
    configs = sorted((REPO / "configs").glob("*.yaml"))
    if args.only:
        configs = [c for c in configs if c.stem in args.only]
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        base_path = code_tree(args.base, Path(tmp))
        try:
            for config in configs:
                before, why_before = run(config, Path(tmp) / f"{config.stem}_base", base_path)
                after, why_after = run(config, Path(tmp) / f"{config.stem}_now", None)
                if before is None or after is None:
                    same = before is None and after is None and why_before == why_after
                    failed |= not same
                    print(f"{config.stem}: {'fails alike' if same else 'FAILS ON ONE SIDE'}: "
                          f"{why_before or why_after}")
                    continue
                worst, where = largest_difference(before, after)
                bad = worst > args.tolerance
                failed |= bad
                print(f"{config.stem}: {len(after)} numbers, largest difference {worst:.3g}"
                      + (f" ({where})" if worst else "") + (" EXCEEDS the tolerance" if bad else ""))
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(Path(tmp) / "tree")], cwd=REPO,
                           capture_output=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
