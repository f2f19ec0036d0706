"""Plugin manager: built-ins are registered exactly like third-party entry-point plugins."""

from __future__ import annotations

import importlib
import importlib.metadata
import os
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import pluggy

from . import hookspecs
from .components import BUILTIN_COMMANDS, Command, FactorType, Initializer, RobotModel, Simulator, Source
from .errors import PluginError
from .graph.variables import VarType, vector_named
from .descriptions.registered import KIND as DESCRIPTIONS, is_description_name

ENTRY_POINT_GROUP = "fusionkit"
BLOCK_ENV = "FUSIONKIT_BLOCK_PLUGINS"  # comma-separated entry-point names not to load

# the core's own components; every robot family, fusionkit's included, is an entry-point plugin
DEFAULT_PLUGINS = (
    "fusionkit.graph.variables",
    "fusionkit.data.builtin_sources",
    "fusionkit.data.static_segments",
    "fusionkit.descriptions.generic",
    "fusionkit.models.cable_robot",
    "fusionkit.time_offset.guess",
    "fusionkit.sweep",
    "fusionkit.crossval.command",
)
API_ATTRIBUTE = "FUSIONKIT_API"  # the API version an entry-point module was written for (absent: "1.0")
OWN_DISTRIBUTION = "fusionkit"  # its entry-point plugins load first: a third-party name clash loses

KINDS = {
    "factor_types": ("register_factor_types", FactorType),
    "sources": ("register_sources", Source),
    "robot_models": ("register_robot_models", RobotModel),
    "initializers": ("register_initializers", Initializer),
    "simulators": ("register_simulators", Simulator),
}
VARIABLE_TYPES = "variable_types"  # VarType instances (not classes): what a variable is and how it is handled
COMMANDS = "commands"  # subcommands `fusionkit <name>` (not config components: no schema)
# everything a plugin registers: the component classes, commands, and robot descriptions ({name: file})
REGISTRATIONS = {**KINDS, COMMANDS: ("register_commands", Command),
                 VARIABLE_TYPES: ("register_variable_types", VarType),
                 DESCRIPTIONS: ("register_robot_descriptions", None)}
RESERVED = {COMMANDS: BUILTIN_COMMANDS}  # names no plugin may register


@dataclass
class Registry:
    """Every registered component by kind and name (and every robot description file, kind
    "robot_descriptions"), which plugin provided it, and the installed plugins that failed to load
    (each a one-line reason naming its distribution and entry point)."""

    components: dict[str, dict[str, Any]] = field(default_factory=lambda: {k: {} for k in REGISTRATIONS})
    provider: dict[tuple[str, str], str] = field(default_factory=dict)
    plugins: list[str] = field(default_factory=list)
    broken: list[str] = field(default_factory=list)

    def get(self, kind: str, name: str) -> Any:
        return self.components[kind].get(name)

    def names(self, kind: str) -> list[str]:
        return sorted(self.components[kind])

    def by_plugin(self) -> dict[str, dict[str, list[str]]]:
        out: dict[str, dict[str, list[str]]] = {p: {k: [] for k in REGISTRATIONS} for p in self.plugins}
        for (kind, name), plugin in sorted(self.provider.items()):
            out[plugin][kind].append(name)
        return out

    def unknown(self, kind: str, name: str) -> str:
        """The message for a `type:` nothing installed provides, naming what is installed and,
        when some plugin failed to load, that it might have been the one."""
        noun = "scenario" if kind == "simulators" else kind[:-1].replace("_", " ")
        text = (f"unknown {noun} {name!r}; installed: "
                f"{', '.join(self.names(kind)) or '(none)'} (see `fusionkit plugins`)")
        if self.broken:
            text += f"; {len(self.broken)} plugin(s) failed to load: " + "; ".join(self.broken)
        return text


def _entry_points() -> list[tuple[str, importlib.metadata.EntryPoint]]:
    """(distribution name, entry point) of every installed `fusionkit` entry point, once per name;
    fusionkit's own plugin families first, then the others by distribution and name."""
    seen, out = set(), []
    for dist in importlib.metadata.distributions():
        for ep in dist.entry_points:
            if ep.group == ENTRY_POINT_GROUP and ep.name not in seen:
                seen.add(ep.name)
                out.append((dist.metadata["Name"] or "?", ep))
    return sorted(out, key=lambda d_ep: (d_ep[0] != OWN_DISTRIBUTION, d_ep[0], d_ep[1].name))


def api_mismatch(declared) -> str | None:
    """Why a plugin written for fusionkit API `declared` ("major.minor", its module's FUSIONKIT_API) cannot load
    into this fusionkit, or None: it needs the same major version and at most this minor one."""
    from .api import API_VERSION
    have = tuple(int(x) for x in API_VERSION.split("."))
    try:
        need = tuple(int(x) for x in str(declared).split("."))
        assert len(need) == 2
    except (ValueError, AssertionError):
        return f"{API_ATTRIBUTE} = {declared!r} is not a version 'major.minor' (this fusionkit provides {API_VERSION})"
    if need[0] != have[0] or need[1] > have[1]:
        return (f"written for fusionkit API {declared}; this fusionkit provides API {API_VERSION} (a plugin needs the "
                "same major version and at most the same minor one): use a fusionkit release with that API, or a "
                "release of the plugin written for this one")
    return None


def _plugin_manager(broken: list[str] | None = None) -> pluggy.PluginManager:
    """Built-ins, then each entry-point plugin; one that fails to import or declares a hook that
    does not exist is left out and described in `broken` (a typo must not pass silently, and one
    broken package must not stop configs that do not use it)."""
    broken = [] if broken is None else broken
    pm = pluggy.PluginManager("fusionkit")
    pm.add_hookspecs(hookspecs)
    for module_name in DEFAULT_PLUGINS:
        pm.register(importlib.import_module(module_name), name=module_name)
    blocked = set(filter(None, (n.strip() for n in os.environ.get(BLOCK_ENV, "").split(","))))
    for dist, ep in _entry_points():
        if ep.name in blocked or pm.get_plugin(ep.name) is not None:
            continue  # blocked: e.g. to show results do not depend on a plugin
        where = f"plugin {ep.name!r} (entry point {ep.name} = {ep.value} of distribution {dist})"
        try:
            plugin = ep.load()
        except Exception as exc:
            broken.append(f"{where}: {exc.__class__.__name__}: {exc}")
            continue
        incompatible = api_mismatch(getattr(plugin, API_ATTRIBUTE, "1.0"))
        if incompatible:
            broken.append(f"{where}: {incompatible}")
            continue
        pm.register(plugin, name=ep.name)
        try:
            pm.check_pending()
        except pluggy.PluginValidationError as exc:
            pm.unregister(name=ep.name)
            broken.append(f"{where}: {exc}")
    return pm


def _provided(impl, pname: str, hook_name: str, base: type | None) -> list[tuple[str, Any]]:
    """(name, component) of what one plugin's registration hook returns, checked; PluginError when
    it fails or returns something that is not a named subclass of `base` (base None: robot
    description files, {name: file})."""
    try:
        provided = impl()
    except Exception as exc:
        raise PluginError(f"plugin {pname}: {hook_name}() failed: {exc.__class__.__name__}: {exc}") from exc
    if base is None:
        return _description_files(provided, pname, hook_name)
    provided = list(provided or [])
    instances = base is VarType  # variable types are VarType values, the other components classes
    for item in provided:
        if not (isinstance(item, base) if instances else isinstance(item, type) and issubclass(item, base)) \
                or not item.name:
            raise PluginError(f"plugin {pname}: {hook_name} returned {item!r}; expected a "
                              f"{base.__name__} {'value' if instances else 'subclass'} with a name")
        if instances and vector_named(item.name):
            raise PluginError(f"plugin {pname}: variable type {item.name!r}: vectorN names are fusionkit's "
                              "(any N); choose another name")
    return [(item.name, item) for item in provided]


def _description_files(provided, pname: str, hook_name: str) -> list[tuple[str, Any]]:
    """{name: file} checked: names a config can give (no path separator, no .yaml suffix), files
    that exist (`importlib.resources` files or paths)."""
    if not isinstance(provided, dict):
        raise PluginError(f"plugin {pname}: {hook_name} returned {provided!r}; expected {{name: file}}")
    for name, file in provided.items():
        if not (isinstance(name, str) and name and is_description_name(name)):
            raise PluginError(f"plugin {pname}: {hook_name} returned the name {name!r}; expected a name "
                              "without a path separator or .yaml/.yml suffix")
        if not (hasattr(file, "is_file") and hasattr(file, "read_text") and file.is_file()):
            raise PluginError(f"plugin {pname}: {hook_name} returned {file!r} for {name!r}; expected an "
                              "existing file (e.g. importlib.resources.files(package) / 'robots' / 'x.yaml')")
    return list(provided.items())


def build_registry(pm: pluggy.PluginManager, broken: list[str] | None = None) -> Registry:
    """Collect each plugin's registrations. A built-in that fails is our bug (PluginError); an
    entry-point plugin that fails, or provides a name another plugin provides, is left out whole
    and described in `registry.broken`."""
    reg = Registry(broken=list(broken or []))
    # only functions marked @hookimpl count (not any attribute that happens to have a hook's name)
    impls = {kind: {i.plugin_name: i.function for i in getattr(pm.hook, hook_name).get_hookimpls()}
             for kind, (hook_name, _) in REGISTRATIONS.items()}
    for pname, _ in pm.list_name_plugin():  # registration order: built-ins first, so they win a clash
        try:
            provided = {kind: _provided(impls[kind][pname], pname, hook_name, base)
                        for kind, (hook_name, base) in REGISTRATIONS.items() if pname in impls[kind]}
            for kind, items in provided.items():
                names = [name for name, _ in items]
                for i, name in enumerate(names):
                    if name in names[:i]:
                        raise PluginError(f"plugin {pname}: {kind[:-1].replace('_', ' ')} {name!r} is "
                                          "registered twice")
                    if name in RESERVED.get(kind, ()):
                        raise PluginError(f"plugin {pname}: command {name!r} is one of fusionkit's own commands")
                    if name in reg.components[kind]:
                        raise PluginError(f"plugin {pname}: {kind[:-1].replace('_', ' ')} {name!r} is "
                                          f"already provided by {reg.provider[(kind, name)]}")
        except PluginError as exc:
            if pname in DEFAULT_PLUGINS:
                raise
            reg.broken.append(str(exc))
            continue
        reg.plugins.append(pname)
        for kind, items in provided.items():
            for name, component in items:
                reg.components[kind][name] = component
                reg.provider[(kind, name)] = pname
    return reg


@lru_cache(maxsize=1)
def registry() -> Registry:
    """The registry of all installed plugins (built once per process)."""
    broken: list[str] = []
    return build_registry(_plugin_manager(broken), broken)


def variable_type(name: str) -> VarType:
    """A registered variable type ('pose3', a plugin's 'cal3_s2', ...) or vectorN; ValueError naming what
    is installed."""
    found = registry().get(VARIABLE_TYPES, name) or vector_named(name)
    if found is None:
        raise ValueError(f"unknown variable type {name!r}; installed: {', '.join(variable_type_names())}")
    return found


def variable_type_names() -> list[str]:
    """Every registered variable type's name, and vectorN."""
    return registry().names(VARIABLE_TYPES) + ["vectorN"]
