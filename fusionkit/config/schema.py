"""JSON schemas of the run config and the robust-kernel block, and located validation."""

from __future__ import annotations

from typing import Any

import jsonschema

from .yamlio import Document

NUMBER = {"type": "number"}
POSITIVE = {"type": "number", "exclusiveMinimum": 0}

ROBUST_SCHEMA = {
    "type": "object",
    "properties": {
        "kernel": {"enum": ["huber", "cauchy", "tukey", "geman_mcclure", "dcs", "welsch", "fair"]},
        "k": POSITIVE,
    },
    "required": ["kernel"],
    "additionalProperties": False,
}

ENTRY = {"type": "object", "required": ["type"], "properties": {"type": {"type": "string"}}}

CONFIG_SCHEMA = {
    "type": "object",
    "properties": {
        "name": {"type": "string"},
        "seed": {"type": "integer"},
        "robots": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"pattern": "^[A-Za-z_][A-Za-z0-9_]*$"},
            "additionalProperties": {
                "type": "object",
                "properties": {
                    "description": {"type": ["string", "object"]},
                    "overrides": {"type": "string"},
                    "states": {
                        "type": "object",
                        "properties": {
                            "stream": {"type": "string"},
                            "type": {"enum": ["pose3", "pose2"]},
                            "every": {"type": "integer", "minimum": 1},
                        },
                        "required": ["stream"],
                        "additionalProperties": False,
                    },
                },
                "required": ["description"],
                "additionalProperties": False,
            },
        },
        "sources": {"type": "array", "items": ENTRY},
        "factors": {"type": "array", "items": ENTRY, "minItems": 1},
        "initializers": {"type": "array", "items": ENTRY},
        "solver": {
            "type": "object",
            "properties": {
                "type": {"enum": ["batch", "isam2", "fixed_lag"]},
                "method": {"enum": ["lm", "gn", "dogleg"]},
                "max_iterations": {"type": "integer", "minimum": 1},
                "relative_tolerance": POSITIVE,
                "absolute_tolerance": POSITIVE,
                "lag": POSITIVE,
                "relinearize_threshold": POSITIVE,
                "max_cost_ratio": POSITIVE,
                "marginals": {"type": "boolean"},
            },
            "additionalProperties": False,
        },
        "truth": {
            "type": "object",
            "properties": {
                "trajectories": {"type": "object", "additionalProperties": {"type": "string"}},
                "calibration": {"type": "string"},
                "align": {"enum": ["none", "se3", "sim3"]},
            },
            "additionalProperties": False,
        },
        "output": {
            "type": "object",
            "properties": {"plots": {"type": "boolean"}},
            "additionalProperties": False,
        },
    },
    "required": ["robots", "factors"],
    "additionalProperties": False,
}


def _describe(error: jsonschema.ValidationError) -> str:
    """A user-facing sentence for one schema violation."""
    if error.validator == "additionalProperties":
        allowed = sorted(error.schema.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed)) if isinstance(error.instance, dict) else []
        return f"unknown key {', '.join(map(repr, extra))}; accepted keys: {', '.join(allowed) or '(none)'}"
    if error.validator == "required":
        return error.message.replace("is a required property", "is required but missing")
    if error.validator == "type":
        return f"expected {error.validator_value}, got {error.instance!r}"
    if error.validator == "enum":
        return f"got {error.instance!r}; accepted: {', '.join(map(str, error.validator_value))}"
    return error.message


def validate_against(doc: Document, schema: dict, instance: Any, path: tuple = ()) -> None:
    """Validate `instance` (found at `path` in `doc`); raise the first error, located."""
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(instance), key=lambda e: (len(e.absolute_path), str(e.absolute_path)))
    if errors:
        err = errors[0]
        raise doc.error(path + tuple(err.absolute_path), _describe(err))
