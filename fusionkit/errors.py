"""Error types. Every user-facing failure is one of these and prints as one line."""

from __future__ import annotations


class FusionkitError(Exception):
    """Base class: a problem the user can fix, reported as one line without a traceback."""


class ConfigError(FusionkitError):
    """Bad configuration: names the file, the line (when known) and the key path."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 path: str | None = None):
        self.file, self.line, self.path, self.detail = file, line, path, message
        where = ""
        if file:
            where = f"{file}:{line}: " if line else f"{file}: "
        key = f"{path}: " if path else ""
        super().__init__(f"{where}{key}{message}")


class PluginError(FusionkitError):
    """A plugin is missing, broken or registers something twice."""


class DataError(FusionkitError):
    """A data file or stream is unreadable or inconsistent (names the file and rows)."""


class SolverError(FusionkitError):
    """The problem cannot be solved as posed: unconstrained variables, divergence, large residual."""
