"""No dangling pointers: every link and repository path in the docs and code comments exists,
nothing points outside the repository, and every paper mentioned is linked to its reference."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.fast

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SKIP_DIRS = {"target", ".git", "node_modules", "site", "__pycache__", ".venv", "build", "dist"}
SOURCE_SUFFIXES = {".py", ".pyi", ".rs", ".md", ".toml", ".sh", ".yml", ".yaml", ".cfg"}

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
# A path into the repository, written in prose, a code span or a comment.
REPO_PATH = re.compile(
    r"(?<![\w./-])((?:python|crates|docs|examples|benchmarks|tests|designs|scripts)/[\w./-]*[\w/])"
)
PAPER = re.compile(r"\b[Pp]aper (00[0-4])\b")
OUTSIDE = re.compile(r"\bshared/|\bDESIGN\.md\b|\bSTYLE\.md\b")


def source_files() -> list[Path]:
    out = []
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT)
        if any(part in SKIP_DIRS or part.startswith(".") for part in rel.parts[:-1]):
            continue
        if path.is_file() and path.suffix in SOURCE_SUFFIXES:
            out.append(path)
    return out


def slug(heading: str) -> str:
    """GitHub's (and mkdocs' toc with the same slug function's) anchor of a heading."""
    text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    names: set[str] = set()
    fenced = False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            base = slug(line.lstrip("#"))
            name, k = base, 1
            while name in names:  # repeated headings get -1, -2, ...
                name, k = f"{base}-{k}", k + 1
            names.add(name)
    return names


def prose(path: Path) -> str:
    """The text of a Markdown file without its fenced blocks (code and output)."""
    keep, fenced = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
        elif not fenced:
            keep.append(line)
    return "\n".join(keep)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_links_resolve(doc):
    bad = []
    for target in LINK.findall(prose(doc)):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        dest = (doc.parent / file_part).resolve() if file_part else doc
        if not dest.exists():
            bad.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading with anchor #{anchor} in {dest.name}")
    assert not bad, f"{doc.name}: " + "; ".join(bad)


@pytest.mark.parametrize("path", source_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_repository_paths_exist_and_nothing_points_outside(path):
    text = path.read_text(encoding="utf-8", errors="replace")
    if path == Path(__file__):
        return  # this file spells out what it looks for
    outside = sorted(set(OUTSIDE.findall(text)))
    assert not outside, (
        f"{path.relative_to(ROOT)} mentions {outside}: files that are not in the repository "
        "(cite papers by authors, title, venue, year and DOI: docs/references.md)"
    )
    # A path may be relative to the repository or to any folder above the file (a crate's
    # own `tests/suite/common.rs`); a glob (`docs/calibration*.md`) is not checked.
    bases = [p for p in path.parents if p == ROOT or ROOT in p.parents]
    missing = set()
    for m in REPO_PATH.finditer(text):
        ref = m[1]
        if text[m.end() : m.end() + 1] in ("*", "{", "<"):
            continue
        if not any((base / ref).exists() for base in bases):
            missing.add(ref)
    assert not missing, f"{path.relative_to(ROOT)} points to missing paths: {sorted(missing)}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_papers_link_to_their_reference(doc):
    if doc.name == "references.md":
        return
    text = prose(doc)
    refs = "docs/references.md" if doc.name == "README.md" else "references.md"
    missing = [n for n in sorted(set(PAPER.findall(text))) if f"]({refs}#paper-{n})" not in text]
    assert not missing, (
        f"{doc.name} mentions paper(s) {missing} without a link [..]({refs}#paper-NNN) to the "
        "reference (link the first mention)"
    )


def test_references_list_every_paper_with_a_doi_or_say_it_is_missing():
    refs = ROOT / "docs" / "references.md"
    text = refs.read_text(encoding="utf-8")
    names = anchors(refs)
    for n in ("000", "001", "002", "003", "004"):
        assert f"paper-{n}" in names
        section = text.split(f"### Paper {n}", 1)[1].split("###", 1)[0]
        assert "doi.org/10." in section or "and DOI: not confirmed" in section, n
    assert "10.1177/0278364919842269" in text  # Till, Aloi and Rucker, IJRR 2019


def test_slug_matches_github():
    assert slug("Doubts about paper 003's equations") == "doubts-about-paper-003s-equations"
    assert slug("Trajectories: saving, plotting, animating") == (
        "trajectories-saving-plotting-animating"
    )
    assert slug("`softrod.calibrate` and the [docs](x.md)") == "softrodcalibrate-and-the-docs"
