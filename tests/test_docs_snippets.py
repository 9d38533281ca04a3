"""Every Python code block of the documentation site runs, so no snippet rots.

The blocks are taken from ``docs/**/*.md`` and from the five environment pages that
``docs/hooks.py`` generates from the env docstrings. Each runs in a fresh namespace, in a
temporary working directory. A block whose first line is ``# doc-test: skip (<reason>)`` is
skipped (keep those few: long runs only).
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```python[^\n]*\n(.*?)^```", re.S | re.M)
SKIP = "# doc-test: skip"
# Generated outputs committed under docs/ (reports, reproduction tables) are not pages we write.
GENERATED_DIRS = ("reproductions", "full-campaign")
INTERNAL = re.compile(
    r"\.\./shared|shared[/]spec|spec 00\d|spec-00[2-4]|spec §|note §|\bissue \d+|the lead\b|not merged", re.I
)
#: the old preset names stay accepted as aliases; they are named only where they are registered,
#: in the tests that check they still work, and in the env docstrings' version history
ALIAS = re.compile(r"spec-00[01]")
ALIAS_ALLOWED = {
    "attitude_envs/presets/pyramid_4wheel.py",
    "attitude_envs/presets/heravi_2017.py",
    "attitude_envs/envs/reaction_wheel.py",
    "attitude_envs/envs/linear_system.py",
    "tests/test_env_api.py",
    "tests/test_linear_system_env.py",
}
#: what the repository-wide sweep reads: the package, its tools, tests and documentation
SWEPT = ("README.md", "CITATION.cff", "mkdocs.yml", "pyproject.toml", "train.py", "constraints.txt")
SWEPT_DIRS = ("attitude_envs", "agents", "baselines", "experiments", "benchmarks", "tests", "tools", "docs")
SWEPT_SUFFIXES = {".py", ".md", ".yml", ".yaml", ".toml", ".json", ".cff", ".txt", ".csv"}


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _pages() -> dict[str, str]:
    pages = {
        str(p.relative_to(DOCS)): p.read_text(encoding="utf-8")
        for p in sorted(DOCS.rglob("*.md"))
        if p.relative_to(DOCS).parts[0] not in GENERATED_DIRS
    }
    pages.update(_hooks().env_pages())
    return pages


PAGES = _pages()


def _blocks() -> list:
    found = []
    for page, text in PAGES.items():
        for m in BLOCK.finditer(text):
            line = text.count("\n", 0, m.start()) + 2
            found.append(pytest.param(m.group(1), id=f"{page}:{line}"))
    return found


BLOCKS = _blocks()


def test_the_docs_have_python_blocks():
    assert len(BLOCKS) >= 15
    skipped = [b for b in BLOCKS if b.values[0].lstrip().startswith(SKIP)]
    assert len(skipped) <= 3, f"keep the skipped set small: {[b.id for b in skipped]}"


@pytest.mark.parametrize("code", BLOCKS)
def test_python_block_runs(code, tmp_path, monkeypatch):
    first = code.lstrip().split("\n", 1)[0]
    if first.startswith(SKIP):
        pytest.skip(first)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    exec(compile(code, "<doc snippet>", "exec"), {"__name__": "__doc_snippet__"})


@pytest.mark.parametrize("page", sorted(PAGES))
def test_pages_have_no_internal_shorthand(page):
    hits = [m.group(0) for m in INTERNAL.finditer(PAGES[page])]
    assert not hits, f"docs/{page}: internal shorthand or references outside the repository: {hits}"


def test_every_env_has_a_generated_page_with_every_section():
    hooks = _hooks()
    import attitude_envs

    assert set(hooks.ENVS) == set(attitude_envs.ENV_IDS) | set(attitude_envs.registration.CONSTRAINED_ENV_IDS)
    for env_id in hooks.ENVS:
        page = hooks.env_page(env_id)
        for section in hooks.SECTIONS:
            assert f"\n## {section}\n" in page, f"{env_id}: no {section!r} section"
        for image in hooks.ENVS[env_id][1]:
            assert (DOCS / "img" / "envs" / image).is_file(), f"{image}: run python docs/gen_figures.py"


def test_generated_tables_of_the_paper_pages_resolve():
    hooks = _hooks()
    for page in sorted((DOCS / "papers").glob("*.md")):
        text = page.read_text(encoding="utf-8")
        for m in hooks._MARKER.finditer(text):
            assert hooks.reproduction_table(m.group(1), m.group(2)).count("\n") >= 2, (page.name, m.group(0))
        for m in hooks._PRESET_MARKER.finditer(text):
            assert hooks.preset_table(m.group(1), m.group(2)).count("\n") >= 2, (page.name, m.group(0))


def _swept_files() -> list[Path]:
    files = [ROOT / name for name in SWEPT if (ROOT / name).is_file()]
    for folder in SWEPT_DIRS:
        files += sorted(
            p
            for p in (ROOT / folder).rglob("*")
            if p.is_file() and p.suffix in SWEPT_SUFFIXES and "__pycache__" not in p.parts
        )
    return files


def test_the_repository_has_no_internal_shorthand_or_outside_references():
    """No file points at documents outside the repository or uses internal shorthand; the old
    preset names appear only where the aliases are registered, tested and recorded."""
    hits, aliases = [], []
    for path in _swept_files():
        rel = path.relative_to(ROOT).as_posix()
        if path == Path(__file__).resolve():  # the patterns themselves
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        hits += [f"{rel}: {m.group(0)}" for m in INTERNAL.finditer(text)]
        if rel not in ALIAS_ALLOWED:
            aliases += [f"{rel}: {m.group(0)}" for m in ALIAS.finditer(text)]
    assert not hits, f"internal shorthand or references outside the repository: {hits}"
    assert not aliases, f"use the preset names pyramid-4wheel / heravi-2017, not the old aliases: {aliases}"
