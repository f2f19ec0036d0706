"""`--set key.path=value` overrides applied to a loaded config before validation."""

from __future__ import annotations

import difflib
from typing import Any

import yaml

from ..errors import ConfigError
from .yamlio import SafeLoader


def parse_key_path(text: str) -> tuple:
    """'factors.1.params.sigma' or 'factors[1].params.sigma' -> ('factors', 1, 'params', 'sigma')."""
    parts: list = []
    for raw in text.replace("[", ".").replace("]", "").split("."):
        if raw == "":
            raise ConfigError(f"--set {text!r}: empty key in path (expected e.g. solver.type=isam2)")
        parts.append(int(raw) if raw.isdigit() else raw)
    return tuple(parts)


def new_key_note(data: Any, path: tuple, assignment: str) -> str | None:
    """When `--set` adds a key the config did not have and an existing key of the same mapping is
    spelled almost alike, a note naming it (a likely typo the schema may still accept); else None."""
    node = data
    for part in path:
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            if not isinstance(node, dict) or not isinstance(part, str):
                return None
            close = difflib.get_close_matches(part, [k for k in node if isinstance(k, str)], n=1, cutoff=0.75)
            if not close:
                return None
            return (f"--set {assignment}: the config had no key {part!r} there and it was added; did you mean "
                    f"the existing {close[0]!r}?")
    return None


def _index(key: str, part, node: list, append: bool = False) -> int:
    """`part` as an index into the list `node` (with `append`, len(node) adds an item), or a
    ConfigError saying which indices exist."""
    if not isinstance(part, int) or part > len(node) or (part == len(node) and not append):
        what = f"index {part} out of range" if isinstance(part, int) else f"{part!r} is not a list index"
        valid = f"0..{len(node) - 1}" if node else "none: the list is empty"
        if append:
            valid += f", or {len(node)} to append"
        raise ConfigError(f"--set {key}: {what} (the list has {len(node)} item(s); indices: {valid})")
    return part


def apply_override(data: dict, assignment: str) -> tuple:
    """Apply one `key.path=value` and return the key path; the value is parsed as YAML (safe).
    A last index one past the end of a list appends (`factors.3={type: ...}` on 3 factors)."""
    if "=" not in assignment:
        raise ConfigError(f"--set {assignment!r}: expected key.path=value")
    key, _, raw = assignment.partition("=")
    path = parse_key_path(key.strip())
    try:
        value: Any = yaml.load(raw, Loader=SafeLoader) if raw.strip() else ""  # noqa: S506
    except yaml.YAMLError:
        raise ConfigError(f"--set {assignment!r}: value is not valid YAML") from None
    node: Any = data
    for i, part in enumerate(path[:-1]):
        nxt = path[i + 1]
        if isinstance(node, list):
            node = node[_index(key, part, node)]
            continue
        if not isinstance(node, dict):
            raise ConfigError(f"--set {key}: {part!r} is not inside a mapping")
        if part not in node or node[part] is None:
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = path[-1]
    if isinstance(node, list):
        i = _index(key, last, node, append=True)
        if i == len(node):
            node.append(value)
        else:
            node[i] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise ConfigError(f"--set {key}: parent is not a mapping or list")
    return path
