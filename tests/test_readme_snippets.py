"""Every ```python block of README.md runs, each in a fresh namespace, so no snippet rots.

Long budgets are shortened here (``SHORT``: the README keeps the real numbers); a block whose
first line holds ``# doc-test: skip`` (a long-running command) is only compiled.
"""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
SKIP = "# doc-test: skip"
#: README text → what the test runs instead (same code, short budget)
SHORT = {
    "agent.learn(max_iterations=100_000, samples_per_iteration=90)": "agent.learn(max_iterations=200, samples_per_iteration=90)",
    "episode_duration_s=600.0)": "episode_duration_s=60.0)",  # the fault comes at 50 s,
}


def _blocks() -> list[tuple[int, str]]:
    text = README.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in BLOCK.finditer(text)]


def test_the_readme_has_python_blocks_and_every_shortened_budget_is_in_one():
    blocks = _blocks()
    assert len(blocks) >= 5
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
