"""Settings declared once: the JSON-schema `default` of a key is its value when a config omits it.

The loader validates an entry as written, then fills the defaults in, so build code reads
`spec["key"]`. A key whose absence means something (no sensor mount, no gap limit, a default
that depends on other keys) has no `default`, and code tests `"key" in spec.data`.
"""

from __future__ import annotations

import copy
from typing import Any

import yaml


def merged(default: Any, given: Any) -> Any:
    """`given` over `default`: mappings merged key by key at every depth, anything else replaced."""
    if not (isinstance(default, dict) and isinstance(given, dict)):
        return given
    out = copy.deepcopy(default)
    for key, value in given.items():
        out[key] = merged(default.get(key), value)
    return out


def with_defaults(schema: dict, instance: Any) -> Any:
    """A copy of the mapping `instance` with the `default` of each property of `schema` it lacks
    (a copy), and a mapping default merged under a given mapping; nested mappings likewise.
    Anything but a mapping is returned as it is (validation reports it)."""
    if not isinstance(instance, dict) or not isinstance(schema, dict):
        return instance
    out = dict(instance)
    for key, sub in schema.get("properties", {}).items():
        if not isinstance(sub, dict):
            continue
        if key in out:
            out[key] = with_defaults(sub, merged(sub["default"], out[key]) if "default" in sub else out[key])
        elif "default" in sub:
            out[key] = with_defaults(sub, copy.deepcopy(sub["default"]))
    return out


def with_default_keywords(schema: dict, defaults: dict) -> dict:
    """A copy of `schema` whose properties carry `default: defaults[key]` (shared subschemas untouched)."""
    props = {key: {**sub, "default": defaults[key]} if key in defaults else sub
             for key, sub in schema.get("properties", {}).items()}
    return {**schema, "properties": props}


def yaml_flow(value: Any) -> str:
    """A value as it is written in a config: 0.005, range, [ax, ay], {rotation: 0.0, translation: 0.0}."""
    text = yaml.safe_dump(value, default_flow_style=True, width=1 << 20).strip()
    return text[:-3].strip() if text.endswith("\n...") else text


def key_rows(schema: dict) -> list[tuple[str, str, str]]:
    """(key, `required` / its default as YAML / `optional`, what it accepts) of each property, in order."""
    from .schema import expected  # jsonschema only when listing
    required = set(schema.get("required", ()))
    rows = []
    for key, sub in schema.get("properties", {}).items():
        status = "required" if key in required else \
            (yaml_flow(sub["default"]) if isinstance(sub, dict) and "default" in sub else "optional")
        rows.append((key, status, expected(sub)))
    return rows
