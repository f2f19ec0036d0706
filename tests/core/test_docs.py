"""The docs stand alone: what users read (docs, READMEs, config and robot comments, plugin
summaries) cites published sources, never the unpublished spec notes, and every relative link
and section anchor in the docs resolves."""

from __future__ import annotations

import argparse
import re
import shlex
import textwrap
from functools import lru_cache
from pathlib import Path

from fusionkit.plugins import KINDS, registry

ROOT = Path(__file__).resolve().parents[2]
# "spec cable_sag.md", "spec eq. 4.3", "the spec's Table 5.2", "Spec fig. 3.3", "(spec `uwb.md`)"
SPEC_REFERENCE = re.compile(r"\bthe spec\b|\bspec(?:'s)?\s+(?:`?[a-z_]+\.md|eqs?\.|fig\.|table)", re.IGNORECASE)
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def user_docs() -> list[Path]:
    return [ROOT / "README.md", ROOT / "benchmarks" / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def user_text_files() -> list[Path]:
    return user_docs() + sorted((ROOT / "configs").glob("*.yaml")) + sorted((ROOT / "robots").glob("*/*.yaml"))


def slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    out, code = set(), False
    for line in path.read_text().splitlines():
        code ^= line.startswith("```")
        if not code and line.startswith("#"):
            out.add(slug(line.lstrip("#")))
    return out


def test_user_facing_text_names_no_spec_reference():
    hits = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
            for path in user_text_files() for n, line in enumerate(path.read_text().splitlines(), 1)
            if SPEC_REFERENCE.search(line)]
    reg = registry()
    hits += [f"{kind} {name}: {cls.summary}" for kind in KINDS for name, cls in reg.components[kind].items()
             if SPEC_REFERENCE.search(cls.summary or "")]
    assert hits == []


def test_spec_reference_pattern_catches_the_old_citations():
    cited = ["(spec cable_sag.md)", "spec eq. 4.3", "the spec's Table 5.2", "Spec fig. 3.3", "(spec `uwb.md`)"]
    assert [bool(SPEC_REFERENCE.search(text)) for text in cited] == [True] * len(cited)
    assert not SPEC_REFERENCE.search("raise spec.error(key, message); build(ctx, spec); thesis eq. 4.3")


def test_relative_links_and_anchors_in_docs_resolve():
    broken = []
    for doc in user_docs():
        for target in LINK.findall(doc.read_text()):
            if re.match(r"[a-z]+:", target):
                continue  # https:, mailto:
            path, _, anchor = target.partition("#")
            dest = (doc.parent / path).resolve() if path else doc
            if not dest.exists():
                broken.append(f"{doc.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                broken.append(f"{doc.relative_to(ROOT)}: {target} (no such section)")
    assert broken == []


def test_every_model_page_cites_its_source():
    pages = sorted((ROOT / "docs" / "models").glob("*.md"))
    assert {p.name for p in pages} >= {"README.md", "unified_graph.md", "cable_rigid.md", "cable_sag.md", "uwb.md"}
    missing = [p.name for p in pages if p.name != "README.md" and "## Source" not in p.read_text()]
    assert missing == []


# ---------------------------------------------------------------------------------------------------------
# Claims the docs make that the code can decide: commands and their options, exit codes, config key paths,
# and what the plugin guide's code imports. Each check is a pure function of a Markdown text, so the tests
# below also run it on a planted wrong claim (it must be caught) besides the real docs.

FENCE = re.compile(r"^\s*```(\w*)")
SHELL_BLOCKS = {"", "bash", "sh", "shell", "console"}  # fenced blocks whose lines are commands (or output)
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*[a-z0-9]")
SEPARATOR = re.compile(r"\s+(?:&&|\|\||\|)\s+|;\s+|\$\(")  # `a\|b` in a table cell is not a pipe
CONFIG_ROOTS = ("robots", "sources", "factors", "initializers", "solver", "truth", "output")
CONFIG_PATH = re.compile(rf"^((?:{'|'.join(CONFIG_ROOTS)})\.[\w.<>-]*[\w>])(?:\s*[=:]\s*(.+))?$")
SET_VALUE = re.compile(r"--set[ =](\S+=\S+)")


def command_docs() -> list[Path]:
    """The docs whose commands, options, exit codes and key paths are checked: README.md and docs/**."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def parts(text: str) -> list[tuple[str, str]]:
    """A Markdown text as ("code", block) for fenced shell blocks and indented blocks (4 spaces after a
    blank line), ("python", block) for fenced Python, and ("prose", paragraph) with its lines joined."""
    out, lines, i, para = [], text.splitlines(), 0, []

    def flush():
        if para:
            out.append(("prose", " ".join(s.strip() for s in para)))
            para.clear()

    while i < len(lines):
        line, fence = lines[i], FENCE.match(lines[i])
        if fence:
            flush()
            j = next((j for j in range(i + 1, len(lines)) if FENCE.match(lines[j])), len(lines))
            kind = "code" if fence.group(1) in SHELL_BLOCKS else fence.group(1)
            out.append((kind, "\n".join(lines[i + 1:j])))
            i = j + 1
        elif line.startswith("    ") and not para and (i == 0 or not lines[i - 1].strip()):
            j = i
            while j < len(lines) and (lines[j].startswith("    ") or not lines[j].strip()):
                j += 1
            out.append(("code", "\n".join(lines[i:j])))
            i = j
        elif line.strip():
            para.append(line)
            i += 1
        else:
            flush()
            i += 1
    flush()
    return out


def spans(paragraph: str) -> list[str]:
    """The inline code spans of a paragraph."""
    return [s.strip() for s in re.findall(r"`([^`]+)`", paragraph)]


def commands(text: str) -> list[str]:
    """Every `fusionkit ...` command line the text writes: in shell code (after a `$ ` prompt, a pipe or
    `&&`, continuation lines joined, comments cut) and in inline code spans. Output lines (`fusionkit:
    error: ...`) and prose ("fusionkit writes ...") are not commands."""
    found = []
    for kind, body in parts(text):
        if kind == "code":
            pieces = [re.split(r"(?:^|\s)#", line)[0] for line in re.sub(r"\\\n\s*", " ", body).splitlines()]
        elif kind == "prose":  # `fusionkit run ...`, and `run --out` (a command's option named in prose)
            pieces = [f"fusionkit {s}" if re.match(r"[a-z][\w-]* --?[a-z]", s) and s.split()[0] in subcommand_names()
                      else s for s in spans(body)]
        else:
            continue
        for piece in pieces:
            if re.match(r"\s*(?:\$\s+)?fusionkit(?: [\w-]+)?:", piece):
                continue  # output (`fusionkit: error: ...`, `fusionkit sweep: 3 run(s) ...`), not a command
            for part in SEPARATOR.split(re.sub(r"^\s*\$\s+", "", piece)):
                part = re.sub(r"^(?:[A-Z_][A-Z0-9_]*=\S*\s+)+", "", part.strip())  # VAR=value fusionkit ...
                if re.match(r"fusionkit(?:\s|$)", part):
                    found.append(" ".join(part.split()))
    return found


def subcommand_names() -> set[str]:
    return set(cli_parsers()[1])


def is_placeholder(word: str) -> bool:
    return word.startswith(("<", "[", ".")) or word.isupper()


def command_problems(command: str, main_parser, subcommands: dict) -> list[str]:
    """What is wrong with one `fusionkit ...` line: an option the main parser does not accept, a command
    that is neither fusionkit's nor an installed plugin's, an option that command does not accept."""
    words = command.split()[1:]
    problems = []
    while words and words[0].startswith("-"):
        if words[0] not in main_parser._option_string_actions:
            problems.append(f"{command}: `fusionkit` accepts no option {words[0]}")
        words.pop(0)
    if not words or is_placeholder(words[0]):
        return problems
    name, rest = words[0], " ".join(words[1:])
    if name not in subcommands:
        return problems + [f"{command}: no command {name!r} (fusionkit has {', '.join(subcommands)})"]
    accepted = subcommands[name]._option_string_actions
    return problems + [f"{command}: `fusionkit {name}` accepts no option {opt}"
                       for opt in OPTION.findall(rest) if opt not in accepted]


@lru_cache(maxsize=1)
def cli_parsers():
    """fusionkit's argument parser with every installed plugin's commands, and its subcommand parsers."""
    from fusionkit.cli.main import parser
    from fusionkit.plugins import COMMANDS
    reg = registry()
    main_parser = parser([reg.get(COMMANDS, name) for name in reg.names(COMMANDS)])
    subparsers = next(a for a in main_parser._actions if isinstance(a, argparse._SubParsersAction))
    return main_parser, dict(subparsers.choices)


def doc_command_problems(text: str, main_parser, subcommands: dict) -> list[str]:
    return [p for command in commands(text) for p in command_problems(command, main_parser, subcommands)]


def test_every_fusionkit_command_in_the_docs_exists_and_accepts_the_options_written_after_it():
    main_parser, subcommands = cli_parsers()
    problems = [f"{doc.relative_to(ROOT)}: {p}" for doc in command_docs()
                for p in doc_command_problems(doc.read_text(), main_parser, subcommands)]
    assert problems == []
    written = {c.split()[1] for doc in command_docs() for c in commands(doc.read_text()) if len(c.split()) > 1}
    assert {"run", "validate", "plugins", "simulate", "view", "sweep", "select-poses"} <= written  # it reads them


def test_command_check_catches_a_wrong_command_or_option():
    main_parser, subcommands = cli_parsers()
    planted = textwrap.dedent("""\
        Run `fusionkit run CONFIG --outdir DIR` (`validate --outdir` too; `plugins` and `sweep.csv` are no
        commands with options) and then:

        ```bash
        $ fusionkit solve configs/quickstart.yaml
        fusionkit validate configs/demo.yaml \\
            --set solver.type=isam2 --plots  # check it
        cat x | fusionkit sweep s.yaml --threads 2
        fusionkit --verbose plugins
        ```

            fusionkit simulate quickstart --out DIR --seed 3 --dry-run

        fusionkit writes no output here (prose); `fusionkit <name> --help`.

            fusionkit: error: x.yaml: unknown key; fusionkit expects --no-such (output)
            fusionkit sweep: 3 run(s) on local (output)
        """)
    assert doc_command_problems(planted, main_parser, subcommands) == [
        "fusionkit run CONFIG --outdir DIR: `fusionkit run` accepts no option --outdir",
        "fusionkit validate --outdir: `fusionkit validate` accepts no option --outdir",
        "fusionkit solve configs/quickstart.yaml: no command 'solve' (fusionkit has "
        + ", ".join(subcommands) + ")",
        "fusionkit validate configs/demo.yaml --set solver.type=isam2 --plots: `fusionkit validate` accepts no "
        "option --plots",
        "fusionkit sweep s.yaml --threads 2: `fusionkit sweep` accepts no option --threads",
        "fusionkit --verbose plugins: `fusionkit` accepts no option --verbose",
        "fusionkit simulate quickstart --out DIR --seed 3 --dry-run: `fusionkit simulate` accepts no option "
        "--dry-run"]


# exit codes: each one a doc states, judged by what its sentence says the exit is for
EXIT_LIST = re.compile(r"\bexit (\d+ [a-z]+(?:, \d+ [a-z]+)+)")  # "exit 2 input, 3 internal, 4 rejected"
EXIT_CODE = re.compile(r"\bexit(?:s| code| status)?(?: with)? (\d+)\b")
EXIT_ROW = re.compile(r"^\|\s*(\d+)\s*\|(.*)\|\s*$")


def exit_code_for(words: str) -> int:
    """The exit code fusionkit's CLI uses for what `words` describe: an internal error, a solution the
    chi-square gate rejected, success, else a problem with the input."""
    from fusionkit.cli.main import EXIT_ERROR, EXIT_INTERNAL, EXIT_REJECTED
    text = words.lower()
    if "internal" in text:
        return EXIT_INTERNAL
    if "reject" in text or "chi-square" in text:
        return EXIT_REJECTED
    return 0 if "success" in text else EXIT_ERROR


def stated_exit_codes(text: str) -> list[tuple[int, str]]:
    """(code, what it is said to be for) of every exit code the text states: "exit code 2", "exits with 4",
    "(exit 3)", "exit 2 input, 3 internal, ..." (with the words before it in its sentence, since the code
    stated before it, and after it up to the end of the clause), and the rows of a `| code | meaning |`
    table."""
    out, table = [], False
    for line in text.splitlines():
        table = bool(re.match(r"^\|\s*code\s*\|", line)) or (table and line.startswith("|"))
        row = EXIT_ROW.match(line) if table else None
        if row:
            out.append((int(row.group(1)), row.group(2).strip()))
    flat = " ".join(text.split())
    for m in EXIT_LIST.finditer(flat):
        out += [(int(code), word) for code, word in (pair.split() for pair in m.group(1).split(", "))]
    previous = 0  # the words describing a code come after the code before it
    for m in EXIT_CODE.finditer(flat):
        if EXIT_LIST.match(flat, m.start()):
            continue
        sentence = re.split(r"[.!?;]\s", flat[max(previous, m.start() - 300):m.start()])[-1]
        clause = re.match(r"[^,;).]*", flat[m.end():]).group(0)
        out.append((int(m.group(1)), sentence + m.group(0) + clause))
        previous = m.end() + len(clause)
    return out


def exit_code_problems(text: str) -> list[str]:
    return [f"exit {code} for: {words!r}; the CLI exits {exit_code_for(words)}"
            for code, words in stated_exit_codes(text) if code != exit_code_for(words)]


def test_exit_codes_the_docs_state_are_the_cli_constants():
    from fusionkit.cli.main import EXIT_ERROR, EXIT_INTERNAL, EXIT_REJECTED
    cli_md = (ROOT / "docs" / "reference" / "cli.md").read_text()
    table = re.search(r"## Exit codes\n(.*?)(?:\n#|$)", cli_md, re.S).group(1)  # cli.md's `| code | meaning |`
    assert sorted(code for code, _ in stated_exit_codes(table)) == sorted({0, EXIT_ERROR, EXIT_INTERNAL,
                                                                            EXIT_REJECTED})
    problems = [f"{doc.relative_to(ROOT)}: {p}" for doc in command_docs() for p in exit_code_problems(doc.read_text())]
    assert problems == []
    assert sum(len(stated_exit_codes(doc.read_text())) for doc in command_docs()) >= 10  # it reads them


def test_exit_code_check_catches_a_wrong_code():
    planted = textwrap.dedent("""\
        A bad config ends with one line and exit code 3. A crash is an internal error (exit 2). A solution
        the chi-square gate refuses is written and exits with 2. Fine: exit 2 input, 4 internal, 3 rejected.
        It goes on (exit code 0 on success), and a typo exits 2; a bug exits 4 (an internal error).

        | code | meaning |
        | --- | --- |
        | 0 | success |
        | 4 | an internal error |
        """)
    stated = stated_exit_codes(planted)
    assert [code for code, _ in stated] == [0, 4, 2, 4, 3, 3, 2, 2, 0, 2, 4]
    # all but `0 success`, `exit 2 input`, `exit code 0 on success` and `a typo exits 2`
    assert [(code, exit_code_for(words)) for code, words in stated if code != exit_code_for(words)] == [
        (4, 3), (4, 3), (3, 4), (3, 2), (2, 3), (2, 4), (4, 3)]
    assert len(exit_code_problems(planted)) == 7


# config key paths: `solver.method`, `--set solver.type=isam2`, `robots.<name>.overrides`, ...
def config_key_problem(key: str, value: str | None = None) -> str | None:
    """Why `key` (set to the YAML text `value`) cannot be a run-config setting, or None when it can be or
    the schema leaves it to a plugin (a factor entry's keys other than `type`)."""
    import jsonschema
    import yaml

    from fusionkit.config.overrides import parse_key_path
    from fusionkit.config.schema import CONFIG_SCHEMA
    from fusionkit.config.yamlio import SafeLoader
    node = CONFIG_SCHEMA
    for part in parse_key_path(key):
        if node.get("type") == "array":
            if not isinstance(part, int):
                return f"{key}: {part!r} is not a list index"
            node = node["items"]
        elif part in node.get("properties", {}):
            node = node["properties"][part]
        elif isinstance(node.get("additionalProperties"), dict):  # robots.<name>, solver.refine.<stage>
            node = node["additionalProperties"]
        elif node.get("additionalProperties") is False:
            return f"{key}: no key {part!r} there; the config accepts {', '.join(node.get('properties', {}))}"
        else:
            return None  # a component entry: its keys are its plugin's
    if value is None or re.search(r"\.\.\.|<|\$", value) or re.fullmatch(r"[A-Za-z]|[A-Z_]+", value):
        return None  # a placeholder: `solver.lag=...`, `solver.updates_per_step: n`, `solver.type=TYPE`
    try:
        data = yaml.load(value, Loader=SafeLoader)  # noqa: S506 (fusionkit's safe loader, as --set reads it)
    except yaml.YAMLError:
        return f"{key}={value}: not YAML"
    error = jsonschema.exceptions.best_match(jsonschema.Draft202012Validator(node).iter_errors(data))
    return None if error is None else f"{key}={value}: {error.message}"


def config_keys(text: str) -> list[tuple[str, str | None]]:
    """(key path, value or None) of every config setting the text names: `--set` assignments of `run` and
    `validate` commands, and inline code `root.key...` (`solver.type`, `solver.method: dogleg`,
    `solver.type=isam2`) with a root of the run config. A paragraph that mentions report.json may name
    its keys the same way (`solver.rejection`): there only keys the config has are checked."""
    out = []
    for command in commands(text):
        words = command.split()
        if len(words) > 1 and words[1] in ("run", "validate"):
            try:
                words = shlex.split(command)
            except ValueError:
                pass
            out += [tuple(a.split("=", 1)) for o, a in zip(words, words[1:]) if o == "--set" and "=" in a
                    and re.split(r"[.\[=]", a)[0] in CONFIG_ROOTS]
    for kind, body in parts(text):
        if kind != "prose":
            continue
        for span in spans(body):
            if span.startswith("fusionkit ") or span.startswith("--set "):
                if span.startswith("--set "):  # `fusionkit ...` spans are read with the commands above
                    settings = [tuple(a.split("=", 1)) for a in SET_VALUE.findall(span)]
                    out += [s for s in settings if re.split(r"[.\[=]", s[0])[0] in CONFIG_ROOTS]
                continue
            m = CONFIG_PATH.match(span)
            if m and not ("report.json" in body and config_key_problem(m.group(1)) is not None):
                out.append((m.group(1), m.group(2)))
    return out


def config_key_problems(text: str) -> list[str]:
    return [p for key, value in config_keys(text) if (p := config_key_problem(key, value))]


def test_config_key_paths_the_docs_name_exist_in_the_config_schema():
    problems = [f"{doc.relative_to(ROOT)}: {p}" for doc in command_docs()
                for p in config_key_problems(doc.read_text())]
    assert problems == []
    named = {key for doc in command_docs() for key, _ in config_keys(doc.read_text())}
    assert {"solver.type", "solver.max_cost_ratio", "truth.align", "output.state_covariances"} <= named


def test_config_key_check_catches_a_wrong_key_or_value():
    from fusionkit.config.schema import CONFIG_SCHEMA
    planted = textwrap.dedent("""\
        Set `solver.max_iteration: 50` (no such key), `solver.method: newton` (no such method),
        `truth.align=sim3` (fine), `robots.<name>.overrides` (fine) and `factors.2.anything` (the plugin's).

        ```bash
        fusionkit run c.yaml --set solver.type=isam3 --set 'solver={type: batch, lag: -1}' --set factors.x.sigma=1
        fusionkit simulate s --set solver.bogus=1
        ```

        `report.json` has `solver.rejection` and `solver.iterations` (report keys: not checked here).
        """)
    problems = config_key_problems(planted)
    named = ["solver.type=isam3", "solver={type: batch, lag: -1}", "factors.x.sigma", "solver.max_iteration",
             "solver.method=newton"]
    assert len(problems) == len(named) and all(p.startswith(f"{n}: ") for p, n in zip(problems, named)), problems
    assert "'isam3' is not one of ['batch', 'isam2', 'fixed_lag']" in problems[0] and "-1" in problems[1]
    assert problems[3] == ("solver.max_iteration: no key 'max_iteration' there; the config accepts "
                           + ", ".join(CONFIG_SCHEMA["properties"]["solver"]["properties"]))


# the plugin guide's code uses the public API only
ALLOWED_FUSIONKIT_MODULES = ("fusionkit.api", "fusionkit.testing")  # api.py: "and fusionkit.testing in tests"
DOTTED = re.compile(r"(?<![\w.])fusionkit\.([A-Za-z_][\w.]*)")


def guide_imports(text: str) -> list[str]:
    """The modules the Python code blocks import (relative imports: the plugin's own modules)."""
    modules = []
    for kind, body in parts(text):
        if kind == "python":
            for line in body.splitlines():
                if m := re.match(r"\s*from\s+([\w.]+)\s+import\b", line):
                    modules.append(m.group(1))
                elif m := re.match(r"\s*import\s+([\w.]+(?:\s*,\s*[\w.]+)*)", line):
                    modules += [name.strip() for name in m.group(1).split(",")]
    return modules


def guide_references(text: str) -> list[str]:
    """Every `fusionkit.<name>` the guide's inline code and Python code refer to (`fusionkit.api.lie`, ...)."""
    refs = []
    for kind, body in parts(text):
        if kind == "python":
            code = "\n".join(line for line in body.splitlines() if not re.match(r"\s*(?:from|import)\s", line))
            refs += [m.rstrip(".") for m in DOTTED.findall(code)]
        elif kind == "prose":
            refs += [m.rstrip(".") for s in spans(body) for m in DOTTED.findall(s)]
    return refs


def non_public_uses(text: str) -> list[str]:
    """Imports of fusionkit modules other than fusionkit.api and fusionkit.testing; references to names
    those modules lack, or to fusionkit's internals. The top-level user functions that fusionkit.api does
    not offer (`fusionkit.run`, `fusionkit.load_config`) may be named; what fusionkit.api offers is named
    through it."""
    import importlib

    import fusionkit
    import fusionkit.api
    bad = [f"import {m}" for m in guide_imports(text)
           if m.split(".")[0] == "fusionkit" and m not in ALLOWED_FUSIONKIT_MODULES]
    for ref in guide_references(text):
        module, _, rest = ref.partition(".")
        if f"fusionkit.{module}" in ALLOWED_FUSIONKIT_MODULES:
            target = importlib.import_module(f"fusionkit.{module}")
            if rest and not hasattr(target, rest.split(".")[0]):
                bad.append(f"fusionkit.{ref} (fusionkit.{module} has no {rest.split('.')[0]!r})")
        elif not (module in fusionkit.__all__ and module not in fusionkit.api.__all__ and not rest):
            bad.append(f"fusionkit.{ref}")
    return bad


def test_plugin_guide_code_uses_only_the_public_api():
    guide = (ROOT / "docs" / "plugin_guide.md").read_text()
    assert non_public_uses(guide) == []
    assert "fusionkit.api" in guide_imports(guide) and "fusionkit.testing" in guide_imports(guide)  # it reads them


def test_public_api_check_catches_an_internal_import_or_name():
    planted = textwrap.dedent("""\
        Mark hooks with `@fusionkit.hookimpl`; use `fusionkit.api.lie` and `fusionkit.api.no_such`,
        `fusionkit.plugins.registry()`, `fusionkit.run(path)` and `fusionkit.testing.check_factor_contract`.

        ```python
        from fusionkit import hookimpl
        from fusionkit.api import FactorType
        from fusionkit.data.association import nearest
        import fusionkit.plugins, numpy
        from .factors import FACTOR_TYPES
        ```
        """)
    assert non_public_uses(planted) == [
        "import fusionkit", "import fusionkit.data.association", "import fusionkit.plugins",
        "fusionkit.hookimpl", "fusionkit.api.no_such (fusionkit.api has no 'no_such')", "fusionkit.plugins.registry"]
