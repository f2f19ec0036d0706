"""`fusionkit` command line: thin argument parsing over the core; errors become one line."""

from __future__ import annotations

import argparse
import json
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from .. import __version__
from ..errors import ConfigError, FusionkitError, SolverError

EXIT_ERROR, EXIT_INTERNAL, EXIT_REJECTED = 2, 3, 4


def _progress(args):
    """A status line on stderr (a terminal only; not with -q) for work that takes a while."""
    if args.quiet or not sys.stderr.isatty():
        return None
    from ..progress import StatusLine
    return StatusLine()


def _warn_broken_plugins() -> None:
    from ..plugins import registry
    for reason in registry().broken:
        print(f"fusionkit: warning: {reason}; its types are unavailable (configs that do not use them run)",
              file=sys.stderr)


def cmd_run(args) -> int:
    from ..config.loader import load_config
    from ..pipeline import estimate
    from ..report.outputs import write_outputs
    from ..report.summary import summary_text
    from ..report.writer import atomic_directory, check_output_folder, output_entries, write_error

    config = load_config(args.config, args.set)
    out = Path(args.out) if args.out else Path("out") / config.name
    inputs = config.input_paths()
    check_output_folder(out, inputs)  # before any work: refuse a folder fusionkit may not replace
    with _status(_progress(args)) as progress:
        result = estimate(config, progress, keep_rejected=True)
        if progress:
            progress.stage("writing outputs")
        try:
            with atomic_directory(out, "run", inputs) as tmp:
                write_outputs(result, tmp, plots=config.output["plots"] and not args.no_plots)
        except OSError as exc:
            raise write_error(out, exc) from None
    print(summary_text(result))
    written = [name + ("/" if (out / name).is_dir() else "") for name in sorted(output_entries(out))]
    print(f"  outputs: {out}/ ({', '.join(written)})")
    if result.solution.rejection:
        print(f"fusionkit: error: {args.config}: {result.solution.rejection}; the outputs were written with status: "
              f"rejected to inspect ({out}/report.json)", file=sys.stderr)
        return EXIT_REJECTED
    return 0


@contextmanager
def _status(progress):
    """Show `progress` while the block runs; erase it after, error or not (the error is the only line)."""
    if progress is None:
        yield None
        return
    with progress:
        yield progress


def cmd_validate(args) -> int:
    from ..config.loader import load_config
    from ..pipeline import build_problem, identifiability_report, read_sources
    from ..report.summary import diagnostic_lines, identifiability_lines
    from ..solve.checks import check_constrained
    from ..solve.factorization import linear_settings

    config = load_config(args.config, args.set)
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    checked = check_constrained(problem, problem.graph(), *linear_settings(config.solver))
    print(f"{args.config}: OK")
    if checked.warning:
        print(f"  warning [ill_conditioned]: {checked.warning}")
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
    for name, initializer in problem.value_source.items():
        print(f"  {name}: no value in the description; initial value from {initializer}")
    for key in sorted(problem.fixed_keys):
        print(f"  {problem.keys.name_of(key)}: fixed (held at its value, not estimated)")
    for line in diagnostic_lines(problem.diagnostics, set(problem.analyses)):
        print(line)
    report = identifiability_report(config, problem, problem.initial, checked.qr, checked.linear)
    found = identifiability_lines(problem, report)
    if found:
        print("  identifiability at the initial values (what this recording can tell; `run` reports it at the "
              "estimate):")
        for line in found:
            print(f"    {line}")
    for note in problem.notes:
        print(f"  note: {note}")
    return 0


def command_usage(cls) -> str:
    """A plugin command's usage line (`fusionkit NAME ...`), from its own arguments."""
    p = argparse.ArgumentParser(prog=f"fusionkit {cls.name}", add_help=False)
    cls().add_arguments(p)
    return " ".join(p.format_usage().split())[len("usage: "):]


def _listed(reg, kind: str, name: str) -> dict:
    """One registered item for `fusionkit plugins`: a component's summary and schema, a command's
    summary and usage, or a robot description's summary and file."""
    from ..plugins import COMMANDS as PLUGIN_COMMANDS, VARIABLE_TYPES
    from ..descriptions.registered import KIND as DESCRIPTIONS, robot_description_data
    if kind == VARIABLE_TYPES:
        vartype = reg.get(kind, name)
        components, axes = vartype.names()
        return {"name": name, "summary": vartype.summary, "dim": vartype.dim, "components": list(components),
                "axes": list(axes)}
    if kind == DESCRIPTIONS:
        return {"name": name, "summary": str(robot_description_data(name).get("summary", "")),
                "file": str(reg.get(kind, name))}
    if kind == PLUGIN_COMMANDS:
        return {"name": name, "summary": reg.get(kind, name).summary, "usage": command_usage(reg.get(kind, name))}
    return {"name": name, "summary": reg.get(kind, name).summary, "schema": reg.get(kind, name).schema}


def _kind_label(kind: str) -> str:
    return "description" if kind == "robot_descriptions" else kind[:-1].replace("_", " ")


COMMON_KEYS = {"factor_types": "label, robust {kernel, k}, noise_scale (a number or estimate)", "sources": "label",
               "initializers": "label"}


def component_keys(reg, name: str) -> list[str]:
    """`fusionkit plugins NAME`: each installed item called NAME with its summary and, for a component,
    its keys: `required`, the default a config that omits it gets, or `optional`; and what each accepts."""
    from ..config.defaults import key_rows
    from ..plugins import REGISTRATIONS
    from ..time_offset.config import KEY as TIME_OFFSET, SCHEMA as TIME_OFFSET_SCHEMA, takes_time_offset
    lines = []
    for kind in REGISTRATIONS:
        if reg.get(kind, name) is None:
            continue
        item = _listed(reg, kind, name)
        lines.append(f"{_kind_label(kind)} {name} ({reg.provider[(kind, name)]}): {item['summary']}")
        if "axes" in item:
            lines.append(f"  value: [{', '.join(item['components'])}]; tangent axes (sigmas): "
                         f"[{', '.join(item['axes'])}]")
            continue
        if "file" in item or "usage" in item:
            lines.append(f"  file: {item['file']}" if "file" in item else f"  usage: {item['usage']}")
            continue
        rows = key_rows(item["schema"])
        widths = [max((len(row[i]) for row in rows), default=0) for i in (0, 1)]
        lines += [f"  {key:<{widths[0]}}  {status:<{widths[1]}}  {what}" for key, status, what in rows]
        if kind in COMMON_KEYS:
            common = COMMON_KEYS[kind]
            if kind == "factor_types" and takes_time_offset(reg.get(kind, name)):
                common += f", {TIME_OFFSET} {{{', '.join(TIME_OFFSET_SCHEMA['properties'])}}}"
            lines.append(f"  (every entry also accepts: {common})")
    if not lines:
        raise FusionkitError(f"nothing installed is called {name!r}; `fusionkit plugins` lists every name")
    return lines


def cmd_plugins(args) -> int:
    from ..plugins import REGISTRATIONS, registry

    reg = registry()
    if args.name:
        print("\n".join(component_keys(reg, args.name)))
        return 0
    listing = {}
    for plugin, provided in reg.by_plugin().items():
        listing[plugin] = {kind: [_listed(reg, kind, n) for n in names] for kind, names in provided.items() if names}
    if args.json:
        print(json.dumps(listing, indent=2))
        return 0
    for plugin, provided in listing.items():
        print(plugin)
        for kind in REGISTRATIONS:
            label = _kind_label(kind)
            for item in provided.get(kind, []):
                print(f"  {label:<12} {item['name']:<28} {item['summary']}")
    return 0


def cmd_simulate(args) -> int:
    from ..report.writer import check_output_folder, write_error
    from ..simulate import write_dataset
    out = Path(args.out)
    check_output_folder(out)
    try:
        with _status(_progress(args)) as progress:
            if progress:
                progress.stage(f"simulating {args.scenario}")
            files = write_dataset(args.scenario, out, args.set, args.seed, args.bag)
    except OSError as exc:
        raise write_error(out, exc) from None
    config = out / "config.yaml"
    hint = f"run it with: fusionkit run {config}" if config in files else f"{args.scenario} writes no config"
    print(f"wrote {len(files)} files to {out}/; {hint}")
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose epilog is made only when help is shown (listing installed
    simulators loads every plugin, which `--version` or a run must not wait for)."""

    def __init__(self, *args, epilog_factory=None, **kwargs):
        super().__init__(*args, formatter_class=argparse.RawDescriptionHelpFormatter, **kwargs)
        self.epilog_factory = epilog_factory

    def format_help(self) -> str:
        if self.epilog_factory is not None:
            self.epilog = self.epilog_factory()
        return super().format_help()


def scenario_listing() -> str:
    """Installed simulators, one line each, and their parameters with default values."""
    from ..plugins import registry
    reg = registry()
    lines = ["installed scenarios (parameters with their defaults; change them with --set KEY=VALUE):"]
    for name in reg.names("simulators"):
        cls = reg.get("simulators", name)
        lines.append(f"  {name:<18} {cls.summary}")
        params = [f"{key}={json.dumps(cls.defaults[key])}" if key in cls.defaults else f"{key} (required)"
                  for key in cls.schema.get("properties", {})]
        if params:
            lines.append("      " + ", ".join(params))
    return "\n".join(lines)


def _common_options(debug_default) -> argparse.ArgumentParser:
    """--debug and -q, accepted before or after the command (after it, they keep the value given
    before it unless given again)."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=debug_default,
                        help="show tracebacks of errors")
    common.add_argument("-q", "--quiet", action="store_true", default=debug_default,
                        help="no progress display on stderr")
    return common


def parser(plugin_commands: list[type] = ()) -> argparse.ArgumentParser:
    """The argument parser: fusionkit's own commands, then `plugin_commands` (Command classes)."""
    p = _Parser(prog="fusionkit", description="Robot calibration and state estimation with factor graphs, "
                "declared in YAML.", parents=[_common_options(False)])
    p.add_argument("--version", action="version", version=f"fusionkit {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = [_common_options(argparse.SUPPRESS)]
    run = sub.add_parser("run", parents=common,
                         help="solve a config and write report.json, calibration.yaml, trajectories, plots")
    run.add_argument("config")
    run.add_argument("--out", help="output folder (default: out/<config name>); replaced only when it is new, "
                     "empty or an earlier fusionkit output, never when it holds an input")
    run.add_argument("--no-plots", action="store_true", help="skip plots/*.png")
    val = sub.add_parser("validate", parents=common, help="check config, data and plugins without solving")
    val.add_argument("config")
    for cmd in (run, val):
        cmd.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="override a config value, e.g. solver.type=isam2 (repeatable)")
    plug = sub.add_parser("plugins", parents=common, help="list installed plugins and what each provides")
    plug.add_argument("name", nargs="?", help="one component (e.g. pose.absolute): its keys, which are required, "
                      "and the default of each optional one")
    plug.add_argument("--json", action="store_true", help="everything as JSON, with each component's schema "
                      "(defaults as `default`)")
    sim = sub.add_parser("simulate", parents=common, epilog_factory=scenario_listing,
                         help="write a synthetic dataset, its truth and a runnable config")
    sim.add_argument("scenario", help="an installed scenario (listed below)")
    sim.add_argument("--out", required=True, help="output folder; replaced only when it is new, empty or an "
                     "earlier fusionkit output")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scenario parameter, e.g. duration=10")
    sim.add_argument("--bag", choices=("ros1", "ros2"), help="write the data as one ROS 1 .bag file or ROS 2 bag "
                     "folder (topic /<stream>; truth also as /truth/<robot>) instead of CSV and TUM files")
    view = sub.add_parser("view", parents=common, help="the 3-D scene of a run's output folder: an open3d window, "
                          "or --png FILE (matplotlib when open3d or OpenGL is missing)")
    view.add_argument("folder", help="an output folder of `fusionkit run` (its scene.json)")
    view.add_argument("--png", metavar="FILE", help="render offscreen into this new PNG file instead of a window")
    view.add_argument("--time", type=float, help="the time (s) whose robot geometry is drawn (default: the last)")
    view.add_argument("--backend", choices=("auto", "open3d", "matplotlib"), default="auto",
                      help="--png renderer: open3d if installed and working (auto), or matplotlib")
    for cls in plugin_commands:
        command = cls()
        cmd = sub.add_parser(cls.name, parents=common, help=cls.summary.replace("%", "%%"), description=cls.summary)
        command.add_arguments(cmd)
        cmd.set_defaults(plugin_command=command)
    return p


# fusionkit's own commands (components.BUILTIN_COMMANDS: names no plugin command may take)
def cmd_view(args) -> int:
    from ..view import open_window, render_png
    folder = Path(args.folder)
    try:
        if args.png:
            file = Path(args.png)
            note = render_png(folder, file, args.time, args.backend)
            print(f"wrote {file}" + (f" ({note})" if note else ""))
        else:
            note = open_window(folder, args.time)
            if note:
                print(note)
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        raise ConfigError(str(exc)) from None
    return 0


COMMANDS = {"run": cmd_run, "validate": cmd_validate, "plugins": cmd_plugins, "simulate": cmd_simulate,
            "view": cmd_view}


def plugin_commands(argv: list[str]) -> list[type]:
    """The installed plugins' Command classes, unless the command is one of fusionkit's own or the
    version is asked for (those parse their arguments without loading any plugin)."""
    word = next((a for a in argv if not a.startswith("-")), None)  # options before the command take no value
    if word in COMMANDS or "--version" in argv:
        return []
    from ..plugins import COMMANDS as KIND, registry
    reg = registry()
    return [reg.get(KIND, name) for name in reg.names(KIND)]


def _one_line(exc: BaseException) -> str:
    """The message with line breaks folded, so an error is always exactly one line on stderr."""
    return " ".join(line.strip() for line in str(exc).splitlines() if line.strip())


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        extra = plugin_commands(argv)
    except FusionkitError as exc:  # a built-in plugin that fails to register: no traceback either
        if "--debug" in argv:
            raise
        print(f"fusionkit: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_ERROR
    args = parser(extra).parse_args(argv)
    from ..threads import one_blas_thread
    try:
        _warn_broken_plugins()
        with one_blas_thread():
            if args.command in COMMANDS:
                return COMMANDS[args.command](args)
            return int(args.plugin_command.run(args))
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
