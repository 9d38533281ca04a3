"""benchmarks/optimum_resolve.py: the sample of the shipped J* table it re-solves."""

from __future__ import annotations

import json

import pytest

from benchmarks import optimum_resolve
from experiments import optimum_table


def test_sample_takes_the_fastest_entries_of_every_env():
    entries = json.loads(optimum_table.shipped_table_path().read_text())["entries"]
    envs = {e["key"]["env_id"] for e in entries}
    picked = optimum_resolve.sample(2)
    assert len(picked) == 2 * len(envs)
    for env in envs:
        mine = [e for e in picked if e["key"]["env_id"] == env]
        slowest_picked = max(e["solve_s"] for e in mine)
        others = [e["solve_s"] for e in entries if e["key"]["env_id"] == env and e not in mine]
        assert all(slowest_picked <= s for s in others)


@pytest.mark.parametrize("per_env", [0, -1])
def test_sample_size_must_be_positive(per_env):
    with pytest.raises(ValueError, match="per_env must be an integer >= 1"):
        optimum_resolve.sample(per_env)
