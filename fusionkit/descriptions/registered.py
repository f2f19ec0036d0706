"""Robot descriptions that plugins ship as package data (hook `register_robot_descriptions`), by
name: a config's `description: arascam` and `fusionkit.api.robot_description_data("arascam")`.

A description source is a name when it has no path separator and no .yaml/.yml suffix; anything
else is a file path."""

from __future__ import annotations

from importlib.resources import files
from typing import TYPE_CHECKING

from ..config.yamlio import Document, parse_yaml
from ..errors import ConfigError

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable

KIND = "robot_descriptions"  # the registry's kind for them
SUFFIXES = (".yaml", ".yml")


def is_description_name(source: str) -> bool:
    """True for a registered description's name, False for a file path."""
    return "/" not in source and "\\" not in source and not source.lower().endswith(SUFFIXES)


def robot_description_files(package: str, folder: str = "robots") -> dict[str, Traversable]:
    """{file stem: file} of every .yaml/.yml file in `folder` of `package` (its package data): what
    a plugin's `register_robot_descriptions` returns, e.g. `robot_description_files(__name__)`."""
    found = (p for p in files(package).joinpath(folder).iterdir() if p.name.lower().endswith(SUFFIXES))
    return {p.name.rsplit(".", 1)[0]: p for p in sorted(found, key=lambda p: p.name)}


def registered_file(name: str, reg, where: Document | None = None, path: tuple = ()) -> Traversable:
    """The file registered as `name`; a ConfigError listing the registered names (located at
    `where`/`path`, the config entry that names it, when given) if none is."""
    file = reg.get(KIND, name)
    if file is None:
        message = (reg.unknown(KIND, name) + f"; a description file is given by its path (e.g. ./{name}.yaml)")
        raise where.error(path, message) if where is not None else ConfigError(message)
    return file


def registered_document(name: str, reg, where: Document, path: tuple) -> Document:
    """The registered description `name` parsed with its key lines (errors name its file)."""
    file = registered_file(name, reg, where, path)
    return parse_yaml(file.read_text(encoding="utf-8"), str(file))


def robot_description_data(name: str, model: str | None = None, user: str = "") -> dict:
    """The robot description a plugin registered as `name`, as a fresh dict (a simulator's
    `robots()` may change it and return it). With `model`: a ConfigError, naming `user` (e.g. the
    simulator), unless the description is of that robot model."""
    from ..plugins import registry
    file = registered_file(name, registry())
    data = parse_yaml(file.read_text(encoding="utf-8"), str(file)).data
    if model is not None and data.get("model") != model:
        raise ConfigError(f"{user + ': ' if user else ''}description {name!r} is a {data.get('model', 'generic')!r} "
                          f"robot; expected a {model} one")
    return data
