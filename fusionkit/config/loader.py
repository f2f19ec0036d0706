"""Load a run config and validate all of it (types, plugins, robots, files, names) before work."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from ..components import CheckScope, Spec
from ..plugins import registry, variable_type
from ..descriptions.calibration_file import apply_calibration, calibration_entries
from ..descriptions.checked import check_with_model
from ..descriptions.description import RobotDescription, load_description
from .defaults import with_defaults
from .overrides import apply_override, new_key_note, parse_key_path
from .schema import CONFIG_SCHEMA, NOISE_SCALE_SCHEMA, ROBUST_SCHEMA, SOLVER_TYPE_DEFAULTS, validate_against
from .yamlio import Document, load_yaml
from ..time_offset.config import KEY as TIME_OFFSET, SCHEMA as TIME_OFFSET_SCHEMA, check_time_offset

FACTOR_KEYS = {"robust": ROBUST_SCHEMA, "noise_scale": NOISE_SCALE_SCHEMA,  # every factor entry's, besides its type's
               TIME_OFFSET: TIME_OFFSET_SCHEMA}


@dataclass
class RobotSetup:
    """A robot of the run: its (possibly overridden) description and how its states are clocked."""

    name: str
    description: RobotDescription
    states: dict[str, Any] | None
    shared: dict[str, tuple[str, str]] = field(default_factory=dict)  # parameter -> (owner robot, its parameter)


@dataclass
class RunConfig:
    doc: Document
    base_dir: Path
    name: str
    seed: int
    robots: dict[str, RobotSetup]
    sources: list[Spec]
    factors: list[Spec]
    initializers: list[Spec]
    solver: dict[str, Any]
    truth: dict[str, Any]
    output: dict[str, Any]
    stream_columns: dict[str, tuple[str, ...]] = field(default_factory=dict)
    stream_source: dict[str, int] = field(default_factory=dict)
    refined_factors: list[Spec] = field(default_factory=list)  # solver.refine applied; empty without it
    notes: list[str] = field(default_factory=list)  # findings while loading (e.g. a --set that added a key)

    def resolve(self, path: str) -> Path:
        p = Path(path)
        return p if p.is_absolute() else self.base_dir / p

    def input_paths(self) -> list[Path]:
        """Everything this run reads: the config, the robot description files, and each existing file
        or folder a string of either names (data, truth, overrides). Output folders must avoid them."""
        docs = [(self.doc, self.base_dir)] + [(r.description.doc, r.description.doc.file.parent)
                                             for r in self.robots.values()]
        found = {self.doc.file.resolve()}
        for doc, base in docs:
            found.add(doc.file.resolve())
            for text in _strings(doc.data):
                path = Path(text).expanduser()
                path = path if path.is_absolute() else base / path
                if text.strip() and path.exists():
                    found.add(path.resolve())
        return sorted(found)


def _strings(node: Any) -> Iterable[str]:
    """Every string value inside a YAML node (mappings, lists), depth first."""
    if isinstance(node, str):
        yield node
    elif isinstance(node, dict):
        for value in node.values():
            yield from _strings(value)
    elif isinstance(node, list):
        for value in node:
            yield from _strings(value)


def _entry_schema(cls: type, extra_keys: dict) -> dict:
    schema = dict(cls.schema)
    props = {"type": {"type": "string"}, "label": {"type": "string"}, **extra_keys,
             **schema.get("properties", {})}
    schema["properties"] = props
    return schema


def _check_entries(doc: Document, specs: list[Spec], kind: str, reg, extra_keys: dict) -> list:
    """Each entry's type must be installed and its keys must fit the type's schema; then the
    schema's defaults fill the keys the entry omits (`spec.data`; the document keeps what was written)."""
    instances = []
    for spec in specs:
        cls = reg.get(kind, spec.type)
        if cls is None:
            raise spec.error("type", reg.unknown(kind, spec.type))
        if "robust" in extra_keys and "robust" in spec.data and not cls.accepts_robust:
            raise spec.error("robust", f"factor type {spec.type} takes no robust kernel (its noise comes from its "
                             "model); remove `robust:` from this entry")
        if "noise_scale" in extra_keys and "noise_scale" in spec.data and not cls.accepts_robust:
            raise spec.error("noise_scale", f"factor type {spec.type} takes no noise scale (its noise comes from its "
                             "model); remove `noise_scale:` from this entry")
        schema = _entry_schema(cls, extra_keys)
        validate_against(doc, schema, spec.data, spec.path)
        spec.data = with_defaults(schema, spec.data)
        instances.append(cls())
    return instances


def solver_settings(raw: dict) -> dict:
    """`solver:` with every default: the schema's, then those that depend on its type."""
    settings = with_defaults(CONFIG_SCHEMA["properties"]["solver"], raw)
    return {**settings, **{k: v for k, v in SOLVER_TYPE_DEFAULTS[settings["type"]].items() if k not in settings}}


def _check_references(specs: list[Spec], instances: list, robots: dict, streams: dict) -> None:
    for spec, inst in zip(specs, instances):
        for key in inst.robot_fields:
            if key in spec.data and spec[key] not in robots:
                raise spec.error(key, f"unknown robot {spec[key]!r}; the config defines: {', '.join(robots)}")
        for key in inst.stream_fields:
            if key in spec.data and spec[key] not in streams:
                raise spec.error(key, f"unknown stream {spec[key]!r}; the sources provide: "
                                 f"{', '.join(sorted(streams)) or '(none)'}")


def _load_robots(doc: Document, base: Path, reg) -> dict[str, RobotSetup]:
    robots = {}
    for name, raw in doc.data["robots"].items():
        path = ("robots", name)
        desc = load_description(raw["description"], base, doc, path + ("description",), reg)
        check_with_model(desc, reg)
        if "overrides" in raw:
            file = base / raw["overrides"]
            _require_file(doc, path + ("overrides",), file)
            cal = load_yaml(file)
            entries = calibration_entries(cal)
            apply_calibration(desc, entries.get(name, {}), cal, name)
        robots[name] = RobotSetup(name, desc, raw.get("states"))
    _resolve_shared(doc, robots)
    return robots


def _resolve_shared(doc: Document, robots: dict[str, RobotSetup]) -> None:
    """Each robot's `shared: {parameter: other_robot/parameter}`: the parameter is the other robot's (one variable,
    the owner's value and prior), followed to the robot that owns it. Both must exist with the same type and
    number of elements, neither time-varying; a cycle is refused."""
    raw = {name: doc.data["robots"][name].get("shared", {}) for name in robots}
    for name, entries in raw.items():
        for param, ref in entries.items():
            path = ("robots", name, "shared", param)
            mine = robots[name].description.parameters.get(param)
            if mine is None:
                raise doc.error(path, f"robot {name!r} has no parameter {param!r}; its parameters: "
                                f"{', '.join(robots[name].description.parameters) or '(none)'}")
            owner, other = ref.split("/")
            if owner not in robots or other not in robots[owner].description.parameters:
                raise doc.error(path, f"{ref!r}: no such robot parameter (expected robot/parameter of this config)")
            theirs = robots[owner].description.parameters[other]
            if (mine.vartype.name, len(mine.values)) != (theirs.vartype.name, len(theirs.values)):
                raise doc.error(path, f"{name}/{param} is {len(mine.values)} {mine.vartype.name}, {ref} is "
                                f"{len(theirs.values)} {theirs.vartype.name}: a shared parameter has one type and size")
            if mine.time_varying or theirs.time_varying:
                raise doc.error(path, "a time-varying parameter follows its own robot's states: it cannot be shared")
            seen, at = {(name, param)}, (owner, other)
            while at[1] in raw.get(at[0], {}):  # follow the shares to the owner
                if at in seen:
                    raise doc.error(path, f"{ref!r}: the shared parameters form a cycle")
                seen.add(at)
                at = tuple(raw[at[0]][at[1]].split("/"))
            robots[name].shared[param] = at


def _state_clock(doc: Document, robot: str, raw: dict, streams: dict[str, tuple[str, ...]]) -> dict:
    """A robot's `states:` checked and completed with its defaults: the variable type (pose3) and the
    family name ("pose" for pose types, else "state"); stamps of a stream (every `every`-th sample),
    or a fixed `rate` (Hz) over [start, end] (s) or over the stream's span."""
    path = ("robots", robot, "states")
    if "stream" in raw and raw["stream"] not in streams:
        raise doc.error(path + ("stream",), f"unknown stream {raw['stream']!r}; the sources provide: "
                        f"{', '.join(sorted(streams)) or '(none)'}")
    if "stream" not in raw and not {"rate", "start", "end"} <= set(raw):
        raise doc.error(path, "expected `stream:` (one state per sample), or `rate:` (Hz) with `start:` and `end:` "
                        "(s) or with `stream:` (its time span)")
    if "rate" in raw and "every" in raw:
        raise doc.error(path + ("every",), "`every` thins a stream's stamps; with `rate:` the states are already "
                        "evenly spaced: drop one of them")
    if "start" in raw and "end" in raw and raw["end"] <= raw["start"]:
        raise doc.error(path + ("end",), f"end {raw['end']} is not after start {raw['start']}")
    try:
        vartype = variable_type(raw.get("type", "pose3"))
    except ValueError as exc:
        raise doc.error(path + ("type",), str(exc)) from None
    raw.setdefault("family", "pose" if vartype.name in ("pose3", "pose2") else "state")
    raw["type"] = vartype.name
    return raw


def _require_file(doc: Document, path: tuple, file: Path) -> None:
    if file.is_dir():
        raise doc.error(path, f"{file} is a folder; expected a file")
    if not file.is_file():
        raise doc.error(path, f"file not found: {file}")


def specs_of(doc: Document, section: str) -> list[Spec]:
    return [Spec(d, doc, (section, i)) for i, d in enumerate(doc.data.get(section) or [])]


def load_config(path: str | Path, overrides: Iterable[str] = ()) -> RunConfig:
    """Load, override and validate a run config; raises ConfigError/DataError on the first problem."""

    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "expected a mapping at the top level (robots:, sources:, factors:, ...)")
    notes = []
    for assignment in overrides:
        note = new_key_note(doc.data, parse_key_path(assignment.partition("=")[0].strip()), assignment) \
            if "=" in assignment else None
        doc.overrides[apply_override(doc.data, assignment)] = assignment
        notes += [note] if note else []
    validate_against(doc, CONFIG_SCHEMA, doc.data)
    reg = registry()
    base = Path(path).resolve().parent
    robots = _load_robots(doc, base, reg)

    sources = specs_of(doc, "sources")
    source_objs = _check_entries(doc, sources, "sources", reg, {})
    scope = CheckScope({n: r.description for n, r in robots.items()}, {},
                       {n: r.states for n, r in robots.items()})
    streams: dict[str, tuple[str, ...]] = {}
    stream_source: dict[str, int] = {}
    for i, (spec, src) in enumerate(zip(sources, source_objs)):
        src.check(spec, scope)
        for sname, cols in src.stream_names(spec, base).items():
            if sname in streams:
                raise spec.error(None, f"stream {sname!r} is already provided by sources[{stream_source[sname]}]")
            streams[sname], stream_source[sname] = cols, i
            scope.stream_origins[sname] = f"sources[{i}]" + (f": {spec['path']}" if "path" in spec.data else "")
    scope.stream_columns = streams

    for name, setup in robots.items():
        if setup.states:
            setup.states = _state_clock(doc, name, setup.states, streams)

    factors = specs_of(doc, "factors")
    factor_objs = _check_entries(doc, factors, "factor_types", reg, FACTOR_KEYS)
    initializers = specs_of(doc, "initializers")
    init_objs = _check_entries(doc, initializers, "initializers", reg, {})
    for specs, objs in ((factors, factor_objs), (initializers, init_objs)):
        _check_references(specs, objs, robots, streams)
        for spec, obj in zip(specs, objs):
            obj.check(spec, scope)
            if specs is factors:
                check_time_offset(spec, type(obj), scope)
    solver = solver_settings(dict(doc.data.get("solver") or {}))
    refined = _refined_factors(doc, solver, factors, factor_objs, scope)
    _check_estimated_noise_scales(factors, solver)

    truth = with_defaults(CONFIG_SCHEMA["properties"]["truth"], dict(doc.data.get("truth") or {}))
    for robot, file in (truth.get("trajectories") or {}).items():
        if robot not in robots:
            raise doc.error(("truth", "trajectories", robot), f"unknown robot {robot!r}; the config defines: "
                            f"{', '.join(robots)}")
        _require_file(doc, ("truth", "trajectories", robot), base / file)
    if "calibration" in truth:
        _require_file(doc, ("truth", "calibration"), base / truth["calibration"])
    for robot, families in (truth.get("states") or {}).items():
        if robot not in robots:
            raise doc.error(("truth", "states", robot), f"unknown robot {robot!r}; the config defines: "
                            f"{', '.join(robots)}")
        for family, file in families.items():
            _require_file(doc, ("truth", "states", robot, family), base / file)

    return RunConfig(doc, base, doc.data.get("name", Path(path).stem), int(doc.data.get("seed", 0)),
                     robots, sources, factors, initializers, solver, truth,
                     with_defaults(CONFIG_SCHEMA["properties"]["output"], dict(doc.data.get("output") or {})),
                     streams, stream_source, refined, notes)


def _check_estimated_noise_scales(factors: list[Spec], solver: dict) -> None:
    """`noise_scale: estimate` re-solves the whole graph each round: a batch solve, Gaussian noise (a robust
    kernel's loss is not a chi-square), one solve per round (not with solver.refine's second one)."""
    for spec in factors:
        if spec.get("noise_scale") != "estimate":
            continue
        if solver["type"] != "batch":
            raise spec.error("noise_scale", f"`estimate` needs solver.type batch (got {solver['type']}): each round "
                             "solves the whole graph again")
        if spec.get("robust"):
            raise spec.error("noise_scale", "`estimate` needs Gaussian noise; remove `robust:` from this entry "
                             "or give the scale as a number")
        if solver.get("refine"):
            raise spec.error("noise_scale", "`estimate` cannot be combined with solver.refine")


def _refined_factors(doc: Document, solver: dict, factors: list[Spec], objs: list, scope) -> list[Spec]:
    """The factor entries of the second solve that `solver.refine` asks for: {label: settings} merged
    into the entries with that label (e.g. a model tolerance tightened once the first solve has
    converged), each checked like any entry. Empty when there is no refine."""
    refine = solver.get("refine")
    if not refine:
        return []
    path = ("solver", "refine")
    if solver["type"] != "batch":
        raise doc.error(path, "only the batch solver refines (a second solve from the first one's estimate)")
    labels = {spec.get("label") for spec in factors if spec.get("label")}
    for label, settings in refine.items():
        if label not in labels:
            raise doc.error(path + (label,), f"no factor entry has label {label!r}; labelled entries: "
                            f"{', '.join(sorted(labels)) or '(none: give one a label)'}")
        for key in ("type", "label", "noise_scale"):
            if key in settings:
                raise doc.error(path + (label, key), f"refine changes settings, not the entry's {key}")
    refined = []
    for spec, obj in zip(factors, objs):
        settings = refine.get(spec.get("label"))
        if settings is None:
            refined.append(spec)
            continue
        merged = Spec({**spec.data, **settings}, doc, spec.path)
        schema = _entry_schema(type(obj), FACTOR_KEYS)
        validate_against(doc, schema, merged.data, path + (spec["label"],))
        merged.data = with_defaults(schema, merged.data)
        obj.check(merged, scope)
        check_time_offset(merged, type(obj), scope)
        refined.append(merged)
    return refined
