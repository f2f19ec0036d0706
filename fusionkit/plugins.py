"""Plugin manager: built-ins are registered exactly like third-party entry-point plugins."""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass, field
from functools import lru_cache

import pluggy

from . import hookspecs
from .components import FactorType, Initializer, RobotModel, Simulator, Source
from .errors import PluginError

ENTRY_POINT_GROUP = "fusionkit"
BLOCK_ENV = "FUSIONKIT_BLOCK_PLUGINS"  # comma-separated entry-point names not to load

DEFAULT_PLUGINS = (
    "fusionkit.data.builtin_sources",
    "fusionkit.robots.generic",
    "fusionkit_plugins.pose",
    "fusionkit_plugins.cable_rigid",
)

KINDS = {
    "factor_types": ("register_factor_types", FactorType),
    "sources": ("register_sources", Source),
    "robot_models": ("register_robot_models", RobotModel),
    "initializers": ("register_initializers", Initializer),
    "simulators": ("register_simulators", Simulator),
}


@dataclass
class Registry:
    """Every registered component by kind and name, and which plugin provided it."""

    components: dict[str, dict[str, type]] = field(default_factory=lambda: {k: {} for k in KINDS})
    provider: dict[tuple[str, str], str] = field(default_factory=dict)
    plugins: list[str] = field(default_factory=list)

    def get(self, kind: str, name: str) -> type | None:
        return self.components[kind].get(name)

    def names(self, kind: str) -> list[str]:
        return sorted(self.components[kind])

    def by_plugin(self) -> dict[str, dict[str, list[str]]]:
        out: dict[str, dict[str, list[str]]] = {p: {k: [] for k in KINDS} for p in self.plugins}
        for (kind, name), plugin in sorted(self.provider.items()):
            out[plugin][kind].append(name)
        return out


def _plugin_manager() -> pluggy.PluginManager:
    pm = pluggy.PluginManager("fusionkit")
    pm.add_hookspecs(hookspecs)
    for module_name in DEFAULT_PLUGINS:
        pm.register(importlib.import_module(module_name), name=module_name)
    for name in filter(None, (n.strip() for n in os.environ.get(BLOCK_ENV, "").split(","))):
        pm.set_blocked(name)  # e.g. a broken third-party plugin, or to show results do not depend on one
    try:
        pm.load_setuptools_entrypoints(ENTRY_POINT_GROUP)
        pm.check_pending()  # a @hookimpl whose name is no hook (a typo) must not pass silently
    except Exception as exc:  # a broken third-party plugin must not look like our bug
        raise PluginError(f"cannot load a plugin from entry-point group {ENTRY_POINT_GROUP!r}: "
                          f"{exc.__class__.__name__}: {exc}") from exc
    return pm


def build_registry(pm: pluggy.PluginManager) -> Registry:
    """Collect each plugin's registrations; duplicate names and wrong base classes are errors."""
    reg = Registry()
    # only functions marked @hookimpl count (not any attribute that happens to have a hook's name)
    impls = {kind: {i.plugin_name: i.function for i in getattr(pm.hook, hook_name).get_hookimpls()}
             for kind, (hook_name, _) in KINDS.items()}
    for plugin in pm.get_plugins():
        pname = pm.get_name(plugin)
        reg.plugins.append(pname)
        for kind, (hook_name, base) in KINDS.items():
            impl = impls[kind].get(pname)
            if impl is None:
                continue
            try:
                provided = impl() or []
            except Exception as exc:
                raise PluginError(f"plugin {pname}: {hook_name}() failed: {exc.__class__.__name__}: {exc}") from exc
            for cls in provided:
                if not (isinstance(cls, type) and issubclass(cls, base)) or not cls.name:
                    raise PluginError(f"plugin {pname}: {hook_name} returned {cls!r}; expected a "
                                      f"{base.__name__} subclass with a name")
                if cls.name in reg.components[kind]:
                    raise PluginError(f"plugin {pname}: {kind[:-1].replace('_', ' ')} {cls.name!r} is "
                                      f"already provided by {reg.provider[(kind, cls.name)]}")
                reg.components[kind][cls.name] = cls
                reg.provider[(kind, cls.name)] = pname
    return reg


@lru_cache(maxsize=1)
def registry() -> Registry:
    """The registry of all installed plugins (built once per process)."""
    return build_registry(_plugin_manager())
