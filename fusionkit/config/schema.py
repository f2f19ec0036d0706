"""JSON schemas of the run config and the robust-kernel block, and located validation."""

from __future__ import annotations

import math
from typing import Any

import jsonschema

from .yamlio import Document

NUMBER = {"type": "number"}
POSITIVE = {"type": "number", "exclusiveMinimum": 0}

# a factor entry's `noise_scale:`: its sigmas multiplied by a number, or by one estimated from the data
# (variance components, fusionkit/solve/noise_scales.py)
NOISE_SCALE_SCHEMA = {"oneOf": [POSITIVE, {"enum": ["estimate"]}]}

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
                    "shared": {"type": "object",
                               "additionalProperties": {"type": "string",
                                                        "pattern": "^[A-Za-z_][A-Za-z0-9_]*/[A-Za-z_][A-Za-z0-9_]*$"}},
                    "states": {
                        "type": "object",
                        "properties": {
                            "stream": {"type": "string"},
                            "every": {"type": "integer", "minimum": 1},
                            "rate": POSITIVE,
                            "start": NUMBER,
                            "end": NUMBER,
                            "type": {"type": "string"},
                            "family": {"type": "string", "pattern": "^[A-Za-z_][A-Za-z0-9_]*$"},
                        },
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
                "type": {"enum": ["batch", "isam2", "fixed_lag"], "default": "batch"},
                "method": {"enum": ["lm", "gn", "dogleg"], "default": "lm"},
                "damping": {"enum": ["marquardt", "levenberg"], "default": "marquardt"},
                "factorization": {"enum": ["cholesky", "qr"]},  # default by type: SOLVER_TYPE_DEFAULTS
                "ordering": {"enum": ["auto", "colamd", "metis"], "default": "auto"},
                "max_iterations": {"type": "integer", "minimum": 1, "default": 100},
                "relative_tolerance": {**POSITIVE, "default": 1e-6},
                "absolute_tolerance": {**POSITIVE, "default": 1e-9},
                "lag": {**POSITIVE, "default": 2.0},
                "warmup": {"type": "number", "minimum": 0, "default": 0},
                "new_states": {"enum": ["initial", "carried"], "default": "initial"},
                "relinearize_threshold": {**POSITIVE, "default": 0.01},
                "updates_per_step": {"type": "integer", "minimum": 1, "default": 1},
                "relinearize_skip": {"type": "integer", "minimum": 1, "default": 1},
                "relinearize_marginal_variables": {"type": "boolean", "default": False},
                "max_cost_ratio": POSITIVE,  # default by type: SOLVER_TYPE_DEFAULTS
                "marginals": {"type": "boolean", "default": True},
                "a_posteriori_sigmas": {"type": "boolean", "default": False},
                "refine": {"type": "object", "additionalProperties": {"type": "object"}},  # none: one solve
            },
            "additionalProperties": False,
        },
        "truth": {
            "type": "object",
            "properties": {
                "trajectories": {"type": "object", "additionalProperties": {"type": "string"}},
                "calibration": {"type": "string"},
                "states": {"type": "object",
                           "additionalProperties": {"type": "object", "additionalProperties": {"type": "string"}}},
                "align": {"enum": ["none", "se2", "se3", "sim3"], "default": "none"},
            },
            "additionalProperties": False,
        },
        "output": {
            "type": "object",
            "properties": {"plots": {"type": "boolean", "default": True},
                           "state_covariances": {"type": "boolean", "default": False}},
            "additionalProperties": False,
        },
    },
    "required": ["robots", "factors"],
    "additionalProperties": False,
}


# solver settings whose default depends on solver.type: iSAM2 and the fixed-lag smoother factor by QR
# (Cholesky declared weakly observed directions, a scale with a loose prior, singular); a fixed-lag
# smoother's full-graph cost is not judged unless asked for (its states keep the estimate they had
# when they left the window), so it has no chi-square gate by default
SOLVER_TYPE_DEFAULTS = {
    "batch": {"factorization": "cholesky", "max_cost_ratio": 10.0},
    "isam2": {"factorization": "qr", "max_cost_ratio": 10.0},
    "fixed_lag": {"factorization": "qr", "max_cost_ratio": math.inf},
}


_TYPE_NAMES = {"object": "a mapping", "array": "a list", "string": "a string", "number": "a number",
               "integer": "an integer", "boolean": "true or false", "null": "null"}


def _is_finite_number(checker, instance) -> bool:
    """JSON-schema "number", but NaN is not one (`.nan` in YAML is never a meaningful setting)."""
    return jsonschema.Draft202012Validator.TYPE_CHECKER.is_type(instance, "number") and \
        not (isinstance(instance, float) and math.isnan(instance))


_Validator = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("number", _is_finite_number))


def expected(schema: Any) -> str:
    """What a (sub)schema accepts, in words: 'a number > 0', 'a mapping with keys a, b', 'one of: x, y'."""
    if not isinstance(schema, dict):
        return "a value"
    if "enum" in schema:
        return "one of: " + ", ".join(map(str, schema["enum"]))
    if "oneOf" in schema and "type" not in schema:  # e.g. a file or a list of files
        return " or ".join(expected(sub) for sub in schema["oneOf"])
    types = schema.get("type")
    if types is None:
        return "a value"
    types = types if isinstance(types, list) else [types]
    words = [_TYPE_NAMES.get(t, t) for t in types]
    text = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
    if types == ["object"] and schema.get("properties"):
        text += " with keys " + ", ".join(schema["properties"])
    if types in (["number"], ["integer"]):
        bounds = [f"{op} {schema[k]:g}" for k, op in (("exclusiveMinimum", ">"), ("minimum", ">="),
                                                      ("exclusiveMaximum", "<"), ("maximum", "<="))
                  if k in schema]
        text += (" " + " and ".join(bounds)) if bounds else ""
    if types == ["array"]:
        lo, hi = schema.get("minItems"), schema.get("maxItems")
        count = (f"{lo}" if lo == hi else f"{lo} to {hi}") if lo is not None and hi is not None else \
            (f"at least {lo}" if lo is not None else (f"at most {hi}" if hi is not None else ""))
        item = expected(schema["items"]) if "items" in schema else "a value"
        plural = _plural(item)
        if plural:  # 'a list of 3 numbers', 'a list of strings'
            text += f" of {count} {plural}" if count else f" of {plural}"
        else:  # 'a list of at least 1 items (each a mapping with keys type)'
            noun = "item" if count.split(" ")[-1] == "1" else "items"
            text += (f" of {count} {noun}" if count else "") + (f" (each {item})" if item != "a value" else "")
    return text


def _plural(words: str) -> str | None:
    """'a number' -> 'numbers', for list descriptions; None when the words are not one simple noun."""
    for article in ("a ", "an "):
        if words.startswith(article) and " " not in words[len(article):] and words != "a value":
            return words[len(article):] + "s"
    return None


def _describe(error: jsonschema.ValidationError) -> str:
    """A user-facing sentence for one schema violation: what was wrong and what is accepted."""
    if error.validator == "additionalProperties":
        allowed = sorted(error.schema.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed)) if isinstance(error.instance, dict) else []
        return f"unknown key {', '.join(map(repr, extra))}; accepted keys: {', '.join(allowed) or '(none)'}"
    if error.validator == "required":
        missing = error.message.split("'")[1] if error.message.count("'") >= 2 else None
        sub = error.schema.get("properties", {}).get(missing)
        hint = f" (expected {expected(sub)})" if sub and expected(sub) != "a value" else ""
        return error.message.replace("is a required property", "is required but missing") + hint
    if error.validator in ("oneOf", "anyOf"):
        alternatives = error.validator_value
        if all(set(a) == {"required"} and len(a["required"]) == 1 for a in alternatives):
            keys = [a["required"][0] for a in alternatives]
            return f"needs exactly one of the keys {', '.join(keys)}"
        return f"got {error.instance!r}; expected " + " or ".join(expected(a) for a in alternatives)
    if error.validator in ("type", "enum", "minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum",
                           "minItems", "maxItems", "minProperties", "pattern"):
        what = "a key" if error.validator == "minProperties" else expected(error.schema)
        if error.validator == "pattern":
            what = f"a string matching {error.validator_value}"
        return f"got {error.instance!r}; expected {what}"
    return error.message


def _error_path(error: jsonschema.ValidationError) -> tuple:
    """Where the error is; an unknown key is located at that key (its own line), not at its parent."""
    path = tuple(error.absolute_path)
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        extra = [k for k in error.instance if k not in error.schema.get("properties", {})]
        if extra:
            path += (extra[0],)
    return path


def validate_against(doc: Document, schema: dict, instance: Any, path: tuple = ()) -> None:
    """Validate `instance` (found at `path` in `doc`); raise the first error, located."""
    validator = _Validator(schema)
    errors = sorted(validator.iter_errors(instance), key=lambda e: (len(e.absolute_path), str(e.absolute_path)))
    if errors:
        err = errors[0]
        raise doc.error(path + _error_path(err), _describe(err))
