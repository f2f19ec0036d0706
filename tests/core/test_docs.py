"""The docs stand alone: what users read (docs, READMEs, config and robot comments, plugin
summaries) cites published sources, never the unpublished spec notes, and every relative link
and section anchor in the docs resolves."""

from __future__ import annotations

import re
from pathlib import Path

from fusionkit.plugins import KINDS, registry

ROOT = Path(__file__).resolve().parents[2]
# "spec cable_sag.md", "spec eq. 4.3", "the spec's Table 5.2", "Spec fig. 3.3", "(spec `uwb.md`)"
SPEC_REFERENCE = re.compile(r"\bthe spec\b|\bspec(?:'s)?\s+(?:`?[a-z_]+\.md|eqs?\.|fig\.|table)", re.IGNORECASE)
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def user_docs() -> list[Path]:
    return [ROOT / "README.md", ROOT / "benchmarks" / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def user_text_files() -> list[Path]:
    return user_docs() + sorted((ROOT / "configs").glob("*.yaml")) + sorted((ROOT / "plugins").glob("*/robots/*.yaml"))


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
