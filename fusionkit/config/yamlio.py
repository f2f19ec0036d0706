"""Safe YAML loading that remembers the line of every key, for one-line error messages."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import re

import yaml

from ..errors import ConfigError


class SafeLoader(yaml.SafeLoader):
    """yaml.SafeLoader that also reads `1e-6` and `1e6` as floats (YAML 1.2), not strings."""


class FastSafeLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """The same, on libyaml's parser in C when PyYAML has it (some 15x faster than the Python one)."""


for _loader in (SafeLoader, FastSafeLoader):
    _loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                       |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                       |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                       |[-+]?\.(?:inf|Inf|INF)
                       |\.(?:nan|NaN|NAN))$""", re.X),
        list("-+0123456789."))


def format_path(path: tuple) -> str:
    """('factors', 1, 'params', 'sigma') -> 'factors[1].params.sigma'."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


@dataclass
class Document:
    """A parsed YAML file: its data, its path, and the 1-based line of each key path."""

    data: Any
    file: Path
    lines: dict[tuple, int] = field(default_factory=dict)
    overrides: dict[tuple, str] = field(default_factory=dict)  # key path -> the `--set` that changed it

    def line_of(self, path: tuple) -> int | None:
        """Line of `path`, or of its closest ancestor that has one."""
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), None)

    def error(self, path: tuple, message: str) -> ConfigError:
        path = tuple(path)
        for where, assignment in self.overrides.items():
            if path[:len(where)] == where:  # the value came from the command line, not from a line of the file
                return ConfigError(f"{message} (from --set {assignment})", file=str(self.file),
                                   path=format_path(path) or None)
        return ConfigError(message, file=str(self.file), line=self.line_of(path),
                           path=format_path(path) or None)


def _record_lines(node: yaml.Node, path: tuple, lines: dict, file: str) -> None:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        seen: dict[tuple, int] = {}
        for key_node, value_node in node.value:
            key = key_node.value
            line = key_node.start_mark.line + 1
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if (key_node.tag, key) in seen:  # PyYAML would silently keep the last one
                    raise ConfigError(f"duplicate key {key!r} (first on line {seen[key_node.tag, key]}); "
                                      "each key may appear once in a mapping",
                                      file=file, line=line, path=format_path(path + (key,)))
                seen[key_node.tag, key] = line
            lines[path + (key,)] = line
            _record_lines(value_node, path + (key,), lines, file)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _record_lines(item, path + (i,), lines, file)


def load_yaml(file: str | Path) -> Document:
    """Read a YAML file safely; raise ConfigError naming the file and line on any problem."""
    file = Path(file)
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", file=str(file)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file ({exc.__class__.__name__}: {exc})", file=str(file)) from None
    return parse_yaml(text, file)


def _parse(text: str, loader: type) -> tuple[yaml.Node | None, Any]:
    return yaml.compose(text, Loader=loader), yaml.load(text, Loader=loader)  # noqa: S506 (safe loaders)


def parse_yaml(text: str, file: str | Path = "<string>") -> Document:
    """Parse YAML text safely, keeping key line numbers (the Python parser words any error)."""
    try:
        try:
            node, data = _parse(text, FastSafeLoader)
        except yaml.YAMLError:
            node, data = _parse(text, SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else None
        raise ConfigError(f"YAML syntax error: {exc.problem or exc.context}",
                          file=str(file), line=line) from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"YAML error: {exc}", file=str(file)) from None
    lines: dict[tuple, int] = {}
    if node is not None:
        _record_lines(node, (), lines, str(file))
    return Document(data={} if data is None else data, file=Path(file), lines=lines)
