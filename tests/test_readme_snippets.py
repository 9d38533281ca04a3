"""Every ```python block of README.md runs, each in a fresh namespace, so no snippet rots.

Long budgets can be shortened here (``SHORT``: the README keeps the real numbers); a block
whose first line holds ``# doc-test: skip`` (a long-running command) is only compiled. The
README is a front page (≤ 10 KB); the longer examples live in the documentation site, whose
blocks ``tests/test_docs_snippets.py`` runs.
"""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
SKIP = "# doc-test: skip"
#: README text → what the test runs instead (same code, short budget)
SHORT: dict[str, str] = {}
#: the front page's size limit, bytes
MAX_BYTES = 10 * 1024


def _blocks() -> list[tuple[int, str]]:
    text = README.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in BLOCK.finditer(text)]


def test_the_readme_has_python_blocks_and_every_shortened_budget_is_in_one():
    blocks = _blocks()
    assert len(blocks) >= 1
    for long in SHORT:
        assert any(long in code for _, code in blocks), f"SHORT entry {long!r} matches no README block any more"


@pytest.mark.parametrize("code", [pytest.param(code, id=f"README.md:{line}") for line, code in _blocks()])
def test_readme_python_block_runs(code, tmp_path, monkeypatch):
    compiled = compile(code, "README.md", "exec")
    if SKIP in code.splitlines()[0]:
        pytest.skip(f"marked {SKIP!r}")
    for long, short in SHORT.items():
        code = code.replace(long, short)
    monkeypatch.chdir(tmp_path)  # a block may write files (results/...)
    compiled = compile(code, "README.md", "exec")
    exec(compiled, {"__name__": "__readme__"})


def test_the_readme_is_a_front_page_with_the_ci_test_command():
    text = README.read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) <= MAX_BYTES, "the README is a front page: move details to docs/"
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8")
    command = next(line.split(" || ")[0] for line in ci.splitlines() if line.startswith("python3 -m venv"))
    assert command in text.splitlines(), "the README's test command must stay identical to the one in .ci/run"
    for env_id in ("ReactionWheel-v0", "AirBearing-v0", "LinearSystem-v0", "FuelSlosh-v0", "Magnetorquer-v0"):
        assert f"`attitude_envs/{env_id}`" in text
