"""docs/design.md is the design the code cites: every citation names a section that exists, no
citation points at a design file outside the repository, the layer table is the one
tests/test_architecture.py enforces, and every package path the document names exists.
"""
import os
import re
from functools import lru_cache
from pathlib import Path

from tests.test_architecture import LAYERS

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "design.md"
# a citation: design.md, then (within a few characters of punctuation) the quoted section name
SKIP = ("build", "demo-output", "__pycache__")
CITATION = re.compile(r'design\.md[^"\n]{0,20}?"([^"\n]+)"')


@lru_cache(maxsize=1)
def _source_list():
    """(relative path, text) of every .py and .md file, hidden folders (the virtual
    environment among them), build outputs and demo output pruned before they are walked."""
    out = []
    for top, dirs, files in os.walk(ROOT):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in SKIP)
        for f in sorted(files):
            if f.endswith((".py", ".md")) and not f.startswith("."):
                p = Path(top) / f
                out.append((p.relative_to(ROOT), p.read_text(encoding="utf-8")))
    return tuple(out)


def _sources():
    yield from _source_list()


def _sections(text: str) -> set[str]:
    return {m.group(1).strip() for m in re.finditer(r"^#{2,3} (.+)$", text, re.MULTILINE)}


def test_the_citation_pattern_reads_the_forms_in_use():
    # the oracle for the check below: the citation forms of the code and of docs/json-keys.md
    text = ('(docs/design.md, "CONTRACT: tip coordinates") and '
            '[`design.md`](design.md) ("CONTRACT: command line"); see docs/design.md for more')
    assert CITATION.findall(text) == ["CONTRACT: tip coordinates", "CONTRACT: command line"]


def test_every_citation_names_a_section_of_the_design_document():
    sections = _sections(DOC.read_text(encoding="utf-8"))
    cited, missing = 0, []
    for rel, text in _sources():
        if rel.name == "test_design_doc.py":
            continue
        for m in CITATION.finditer(text):
            cited += 1
            if m.group(1) not in sections:
                line = text.count("\n", 0, m.start()) + 1
                missing.append(f"{rel}:{line}: {m.group(1)!r}")
    assert missing == [], f"sections of docs/design.md: {sorted(sections)}"
    assert cited >= 10          # the code's citations are there (not a vacuous pass)


def test_no_citation_of_a_design_file_outside_the_repository():
    stale = [f"{rel}:{text.count(chr(10), 0, m.start()) + 1}"
             for rel, text in _sources() if rel.name != "test_design_doc.py"
             for m in re.finditer(r'DESIGN(\.md|\s+")|shared/DESIGN', text)]
    assert stale == []


def test_the_layer_table_is_the_one_the_architecture_test_enforces():
    text = DOC.read_text(encoding="utf-8")
    body = text.split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    table = {}
    for row in re.finditer(r"^\| (\d+) \| ([^|]+) \|", body, re.MULTILINE):
        for name in re.findall(r"`([\w]+)`", row.group(2)):
            table[name] = int(row.group(1))
    assert table == LAYERS


def test_every_package_path_the_document_names_exists():
    text = DOC.read_text(encoding="utf-8")
    paths = set(re.findall(r"`((?:planner|docs|tests)/[\w/.-]*)`", text))
    assert len(paths) >= 10
    assert sorted(p for p in paths if not (ROOT / p).exists()) == []
