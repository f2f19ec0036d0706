"""`fusionkit` command line: thin argument parsing over the core; errors become one line."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from ..errors import FusionkitError, SolverError

EXIT_ERROR, EXIT_INTERNAL = 2, 3


def _progress():
    if not sys.stderr.isatty():
        return None

    def show(it: int, cost: float) -> None:
        text = f"iteration {it}" + ("" if cost != cost else f", cost {cost:.6g}")
        print(f"\r  {text}   ", end="", file=sys.stderr, flush=True)
    return show


def _output_folder(out: Path) -> Path:
    """Fail before any work if `out` cannot become a folder (it, or a parent, is an existing file)."""
    for part in (out, *out.parents):
        if part.exists():
            if not part.is_dir():
                where = "exists and is not a folder" if part == out else f"is inside {part}, which is a file"
                raise FusionkitError(f"--out {out}: {where}; expected a folder path (created, or replaced "
                                     "only when everything succeeded)")
            break
    return out


def _write_error(out: Path, exc: OSError) -> FusionkitError:
    return FusionkitError(f"--out {out}: cannot write {exc.filename or out} ({exc.strerror or exc}); nothing was "
                          "written; expected a writable folder")


def cmd_run(args) -> int:
    from ..config.loader import load_config
    from ..pipeline import estimate
    from ..report.outputs import write_outputs
    from ..report.summary import summary_text
    from ..report.writer import atomic_directory

    config = load_config(args.config, args.set)
    out = _output_folder(Path(args.out) if args.out else Path("out") / config.name)
    progress = _progress()
    try:
        result = estimate(config, progress)
    except BaseException:
        if progress:
            print("\r\033[K", end="", file=sys.stderr)  # erase the progress line: the error is the only line
        raise
    if progress:
        print(file=sys.stderr)
    try:
        with atomic_directory(out) as tmp:
            write_outputs(result, tmp, plots=config.output.get("plots", True) and not args.no_plots)
    except OSError as exc:
        raise _write_error(out, exc) from None
    print(summary_text(result))
    print(f"  outputs: {out}/ (report.json, calibration.yaml, trajectories/, plots/)")
    return 0


def cmd_validate(args) -> int:
    from ..config.loader import load_config
    from ..pipeline import build_problem, read_sources
    from ..report.summary import diagnostic_lines
    from ..solve.checks import check_constrained
    from ..solve.factorization import linear_settings

    config = load_config(args.config, args.set)
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    check_constrained(problem, problem.graph(), *linear_settings(config.solver))
    print(f"{args.config}: OK")
    for name, s in streams.items():
        print(f"  stream {name}: {len(s)} samples, t = {s.t[0]:.3f} .. {s.t[-1]:.3f} s, columns {', '.join(s.columns)}")
    for robot, states in problem.states.items():
        print(f"  robot {robot}: {len(states)} states")
    counts: dict[str, int] = {}
    for r in problem.records:
        counts[r.label] = counts.get(r.label, 0) + 1
    for label, n in counts.items():
        print(f"  {label}: {n} factors")
    print(f"  {problem.initial.size()} variables, {len(problem.records)} factors; every variable is constrained")
    for line in diagnostic_lines(problem.diagnostics):
        print(line)
    for note in problem.notes:
        print(f"  note: {note}")
    return 0


def cmd_plugins(args) -> int:
    from ..plugins import KINDS, registry

    reg = registry()
    listing = {}
    for plugin, provided in reg.by_plugin().items():
        listing[plugin] = {kind: [{"name": n, "summary": reg.get(kind, n).summary,
                                   "schema": reg.get(kind, n).schema} for n in names]
                           for kind, names in provided.items() if names}
    if args.json:
        print(json.dumps(listing, indent=2))
        return 0
    for plugin, provided in listing.items():
        print(plugin)
        for kind in KINDS:
            for item in provided.get(kind, []):
                print(f"  {kind[:-1].replace('_', ' '):<12} {item['name']:<28} {item['summary']}")
    return 0


def cmd_simulate(args) -> int:
    from ..simulate import write_dataset
    out = _output_folder(Path(args.out))
    try:
        files = write_dataset(args.scenario, out, args.set, args.seed)
    except OSError as exc:
        raise _write_error(out, exc) from None
    print(f"wrote {len(files)} files to {out}/; run it with: fusionkit run {out / 'config.yaml'}")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="fusionkit", description="Robot calibration and state estimation with "
                                "factor graphs, declared in YAML.")
    p.add_argument("--debug", action="store_true", help="show tracebacks")
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve a config and write report.json, calibration.yaml, trajectories, plots")
    run.add_argument("config")
    run.add_argument("--out", help="output folder (default: out/<config name>)")
    run.add_argument("--no-plots", action="store_true", help="skip plots/*.png")
    val = sub.add_parser("validate", help="check config, data and plugins without solving")
    val.add_argument("config")
    for cmd in (run, val):
        cmd.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="override a config value, e.g. solver.type=isam2 (repeatable)")
    plug = sub.add_parser("plugins", help="list installed plugins and what each provides")
    plug.add_argument("--json", action="store_true")
    sim = sub.add_parser("simulate", help="write a synthetic dataset, its truth and a runnable config")
    sim.add_argument("scenario", help="a simulator name (see `fusionkit plugins`)")
    sim.add_argument("--out", required=True)
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a simulator parameter, e.g. duration=10")
    return p


COMMANDS = {"run": cmd_run, "validate": cmd_validate, "plugins": cmd_plugins, "simulate": cmd_simulate}


def _one_line(exc: BaseException) -> str:
    """The message with line breaks folded, so an error is always exactly one line on stderr."""
    return " ".join(line.strip() for line in str(exc).splitlines() if line.strip())


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except FusionkitError as exc:
        if args.debug:
            raise
        where = f"{args.config}: " if isinstance(exc, SolverError) and getattr(args, "config", None) else ""
        print(f"fusionkit: error: {where}{_one_line(exc)}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("fusionkit: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `fusionkit plugins | head`: the reader left, nothing to report
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # as the Python docs advise
        return 0
    except Exception as exc:  # never a traceback by default
        if args.debug:
            raise
        print(f"fusionkit: internal error: {exc.__class__.__name__}: {_one_line(exc)} (rerun with --debug for the "
              "traceback and please report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
