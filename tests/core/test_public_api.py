"""The public plugin API: every plugin in this repository (and the example third-party package)
imports fusionkit only through `fusionkit.api`, and no plugin family reaches into another's modules
-- exactly as a third-party package would be written."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import fusionkit.api

REPO = Path(__file__).resolve().parents[2]
PLUGIN_ROOTS = [REPO / "plugins", REPO / "examples" / "fusionkit-altimeter" / "fusionkit_altimeter"]


def plugin_files() -> list[Path]:
    return sorted(p for root in PLUGIN_ROOTS for p in root.rglob("*.py"))


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every absolute import in the file, at any depth (functions included)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


def family_of(path: Path) -> str:
    return path.relative_to(REPO).parts[1] if path.is_relative_to(REPO / "plugins") else "altimeter"


def test_plugins_import_fusionkit_only_through_the_public_api():
    offending = [f"{p.relative_to(REPO)}:{line}: {module}" for p in plugin_files()
                 for line, module in imported_modules(p)
                 if (module == "fusionkit" or module.startswith("fusionkit.")) and module != "fusionkit.api"]
    assert not offending, "plugins must import from fusionkit.api only:\n" + "\n".join(offending)


def test_no_plugin_family_imports_another_familys_modules():
    offending = [f"{p.relative_to(REPO)}:{line}: {module}" for p in plugin_files()
                 for line, module in imported_modules(p)
                 if module.startswith("fusionkit_plugins.") and module.split(".")[1] != family_of(p)]
    assert not offending, "a plugin family uses only the public API, not another plugin:\n" + "\n".join(offending)


def test_every_public_name_exists_and_is_documented_in_the_plugin_guide():
    guide = (REPO / "docs" / "plugin_guide.md").read_text()
    assert fusionkit.api.API_VERSION.count(".") == 1
    missing = [name for name in fusionkit.api.__all__ if not hasattr(fusionkit.api, name)]
    assert not missing
    undocumented = [name for name in fusionkit.api.__all__ if f"`{name}" not in guide]
    assert not undocumented, f"add to docs/plugin_guide.md: {undocumented}"


@pytest.mark.parametrize("path", sorted((REPO / "plugins").rglob("*.py")), ids=lambda p: str(p.relative_to(REPO)))
def test_every_plugin_module_imports(path):
    """Each module of fusionkit_plugins imports (a syntax error, a wrong name imported, a module-level mistake in a
    rarely used module would otherwise hide until a user reaches it)."""
    import importlib
    parts = path.relative_to(REPO / "plugins").with_suffix("").parts
    module = importlib.import_module(".".join(("fusionkit_plugins",) + parts[:-1] if parts[-1] == "__init__"
                                              else ("fusionkit_plugins",) + parts))
    assert module.__file__ and Path(module.__file__).resolve() == path.resolve()


def ctx_attributes(path: Path) -> list[tuple[int, str]]:
    """(line, name) of every `ctx.<name>` the file reads or calls."""
    return [(node.lineno, node.attr) for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "ctx"]


def test_plugins_use_only_the_build_context_protocol():
    """Every `ctx.<name>` in the plugins (and the example third-party package) is an operation of
    fusionkit.api.BuildContext: none reaches the core's internals (ctx.initial, ctx.keys, ctx.records, ctx.config,
    ctx.add_record)."""
    from fusionkit.graph.context import MEMBERS
    used = {(p, line, name) for p in plugin_files() for line, name in ctx_attributes(p)}
    assert len(used) > 400
    outside = sorted(f"{p.relative_to(REPO)}:{line}: ctx.{name}" for p, line, name in used if name not in MEMBERS)
    assert not outside, "not in fusionkit.api.BuildContext:\n" + "\n".join(outside)


def test_the_core_build_context_implements_the_protocol_and_a_stray_use_is_caught(tmp_path):
    from fusionkit.config.loader import load_config
    from fusionkit.graph.builder import BuildContext as Concrete
    from fusionkit.pipeline import read_sources
    config = load_config(REPO / "configs" / "arm_calibration.yaml", ["sources.0.params.configurations=5"])
    ctx = Concrete(config, read_sources(config)[0])
    assert isinstance(ctx, fusionkit.api.BuildContext)
    stray = tmp_path / "stray.py"
    stray.write_text("def build(ctx, spec):\n    return ctx.initial.atPose3(0), ctx.keys.get('a', 'b')\n")
    from fusionkit.graph.context import MEMBERS
    assert [name for _, name in ctx_attributes(stray) if name not in MEMBERS] == ["initial", "keys"]


def test_plugins_are_given_the_protocol_only_and_the_core_state_is_out_of_their_reach():
    """The `ctx` a plugin's build receives answers every BuildContext operation with the core's own and refuses the
    rest (ctx.initial, ctx.keys, ctx.records, ctx.config, ctx.add_record) with one line naming the protocol; it cannot
    be assigned to."""
    from fusionkit.config.loader import load_config
    from fusionkit.graph.builder import BuildContext as Concrete
    from fusionkit.graph.context import MEMBERS, for_plugins
    from fusionkit.pipeline import read_sources
    config = load_config(REPO / "configs" / "arm_calibration.yaml", ["sources.0.params.configurations=5"])
    core = Concrete(config, read_sources(config)[0])
    ctx = for_plugins(core)
    assert ctx is for_plugins(core) and isinstance(ctx, fusionkit.api.BuildContext)
    assert all(callable(getattr(ctx, name)) for name in MEMBERS)
    assert ctx.robot("arm") is core.robot("arm")
    for hidden in ("initial", "keys", "records", "config", "add_record", "notes"):
        assert hasattr(core, hidden)
        with pytest.raises(AttributeError, match=rf"ctx\.{hidden} is not part of fusionkit.api.BuildContext"):
            getattr(ctx, hidden)
    with pytest.raises(AttributeError, match="cannot be set"):
        ctx.initial = None
