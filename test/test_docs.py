"""The documents hold together: README.md is short and maps docs/ exactly, every relative
link of README.md and docs/*.md resolves, the README's `make` commands are targets of the
Makefile, the pages that describe what is carry no project history, and every file and name
docs/developing.md points to exists. (The README's tour is run by test_readme_tour.py, the
node page's blocks by test_docs_node.py and test_controller_api.py.)"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = REPO / "docs"
MAP = "## Map of docs/"
MAX_README_LINES = 200

LINK = re.compile(r"\]\(([^)\s]+)\)")
NO_HISTORY = ("README.md", "docs/install.md", "docs/testing.md", "docs/command_line.md",
              "docs/node.md", "docs/live_view.md", "docs/logs.md", "docs/reliability.md",
              "docs/energy.md", "docs/verification.md", "docs/benchmarks.md",
              "docs/developing.md")
HISTORY = re.compile(r"\bissue \d+|\bthis (session|branch|round)\b|\bprevious session\b|"
                     r"\bagainst main\b|\bused to\b", re.I)


def readme() -> str:
    return README.read_text(encoding="utf-8")


def mapped_pages() -> list[str]:
    text = readme()
    start = text.index(MAP)
    end = text.find("\n## ", start + len(MAP))
    section = text[start:end if end >= 0 else len(text)]
    return re.findall(r"^\| \[[^\]]+\]\(docs/([^)]+)\) \|", section, re.M)


def test_the_readme_is_at_most_200_lines():
    lines = readme().count("\n") + (not readme().endswith("\n"))
    assert lines <= MAX_README_LINES, f"README.md has {lines} lines"


def test_the_map_names_every_page_of_docs_and_only_pages_that_exist():
    pages = mapped_pages()
    assert len(pages) == len(set(pages)), "a page is mapped twice"
    on_disk = sorted(p.name for p in DOCS.glob("*.md"))
    assert sorted(pages) == on_disk, (
        f"not in the map: {sorted(set(on_disk) - set(pages))}; "
        f"mapped but missing: {sorted(set(pages) - set(on_disk))}")


@pytest.mark.parametrize("page", ["README.md"] + sorted(
    f"docs/{p.name}" for p in DOCS.glob("*.md")))
def test_every_relative_link_resolves(page):
    path = REPO / page
    broken = []
    for target in LINK.findall(path.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+://", target) or target.startswith(("#", "mailto:")):
            continue
        if not (path.parent / target.split("#")[0]).exists():
            broken.append(target)
    assert not broken, f"{page}: broken links {broken}"


def makefile_targets() -> set[str]:
    text = (REPO / "Makefile").read_text()
    return set(re.findall(r"^([a-z][a-z0-9-]*):", text, re.M))


def test_the_readme_make_commands_are_makefile_targets():
    """The two-commands block (make demo, make test are run by CI and by a newcomer, not by a
    test: they take minutes); every `make X` the README names is a target."""
    named = set(re.findall(r"`make ([a-z][a-z0-9-]*)", readme()))
    block = re.findall(r"^```sh\n(.*?)^```", readme(), re.M | re.S)[0]
    in_block = re.findall(r"^make ([a-z][a-z0-9-]*)", block, re.M)
    assert in_block == ["demo", "test"]
    assert named | set(in_block) <= makefile_targets(), named - makefile_targets()


def test_a_makefile_target_that_does_not_exist_is_caught():
    assert "demo" in makefile_targets() and "dmeo" not in makefile_targets()


@pytest.mark.parametrize("page", NO_HISTORY)
def test_the_pages_say_what_is_not_how_it_came_to_be(page):
    found = [m.group(0) for m in HISTORY.finditer((REPO / page).read_text(encoding="utf-8"))]
    assert not found, f"{page}: {found}"


def developing() -> str:
    return (DOCS / "developing.md").read_text(encoding="utf-8")


def named_paths(text: str) -> set[str]:
    return set(re.findall(r"`((?:rod_sim|test|config|docs)/[\w./]*?)`", text))


def named_identifiers(text: str) -> set[str]:
    """Backticked Python names (``Load.value``, ``erk.fixed_run``, ``OUTPUTS``), without
    paths, placeholders (``<name>_rhs``) and code with spaces or calls."""
    out = set()
    for code in re.findall(r"`([^`\n]+)`", text):
        if "/" in code or "<" in code or " " in code or "(" in code or "-" in code:
            continue
        if re.fullmatch(r"[A-Za-z_][\w]*(\.[A-Za-z_]\w*)*", code) and not code.endswith(".py"):
            out.add(code)
    return out


def source_words() -> set[str]:
    words: set[str] = set()
    for root in ("rod_sim", "test"):
        for path in (REPO / root).rglob("*.py"):
            if path.resolve() == Path(__file__).resolve():    # names checked here, not defined
                continue
            words.update(re.findall(r"[A-Za-z_]\w*", path.read_text(encoding="utf-8")))
    return words


def test_every_file_developing_md_names_exists():
    paths = named_paths(developing())
    assert len(paths) > 25, sorted(paths)
    missing = sorted(p for p in paths if not (REPO / p.rstrip("/")).exists())
    assert not missing, missing


def test_every_name_developing_md_names_is_in_the_code():
    """Each dotted part of every name is a word of the sources (a renamed or removed function
    fails here; prose words in backticks, e.g. `name`, are attributes of the code too)."""
    names = named_identifiers(developing())
    assert {"OUTPUTS", "LOAD_SHAPES", "scripted_value", "INTEGRATORS", "MODELS",
            "COMPILE_CPU_S"} <= names
    words = source_words()
    missing = sorted(n for n in names if not set(n.split(".")) <= words)
    assert not missing, missing


def test_a_misspelt_name_would_be_caught():
    words = source_words()
    assert "scripted_value" in words and "scripted_valeu" not in words
