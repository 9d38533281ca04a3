"""The J* table answers for the episode asked for (nothing checked it before).

* The key (:func:`~experiments.optimum_table.episode_key`, hashed by ``key_hash``) distinguishes
  reset options: the same env, kwargs and seed with other options is another episode (empty
  options are no options, and the order of their keys does not matter), and a campaign's J*
  specs keep two cells apart that differ only in their scenario's options.
* A looked-up entry is the episode asked for: for every episode of the campaigns the shipped
  table covers, the entry ``resolve`` takes (the campaign's path) stores the key of that episode
  and its hash, and gives the campaign that entry's J*; an episode the table does not hold (the
  same with reset options) is looked up as missing, not as its option-less neighbour.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from experiments import optimum_table
from experiments.campaign.jobs import episode_jobs
from experiments.campaign.spec import load_campaign
from experiments.optimum_table import SHIPPED, episode_key, episode_specs, key_hash, load_table, resolve

ENV = "attitude_envs/AirBearing-v0"
KWARGS = {"preset": "air-bearing-85kg"}
#: the plain campaign names among the shipped cells (``full:rw:...`` names a subset of ``full``)
CAMPAIGNS = [name for name in SHIPPED if ":" not in name]


def test_the_key_distinguishes_reset_options():
    def h(options):
        return key_hash(episode_key(ENV, KWARGS, 3, options))

    plain = h(None)
    assert h({}) == plain  # reset(options={}) is reset(options=None)
    one, other = h({"initial_rate_rad_s": [0.1, 0.0, 0.0]}), h({"initial_rate_rad_s": [0.2, 0.0, 0.0]})
    assert len({plain, one, other}) == 3
    assert h({"a": 1, "b": 2}) == h({"b": 2, "a": 1})
    assert episode_key(ENV, KWARGS, 3, {"a": 1})["options"] == {"a": 1}


def test_campaign_specs_keep_cells_that_differ_only_in_options_apart():
    data = {
        "name": "options-apart",
        "seeds": [0],
        "envs": [
            {
                "name": "ab",
                "id": ENV,
                "kwargs": KWARGS,
                "scenarios": [{"name": "plain"}, {"name": "pushed", "options": {"a": 1}}],
            }
        ],
        "agents": [{"name": "zero", "policy": "zero"}],
    }
    specs = episode_specs(episode_jobs(load_campaign(data), Path("/nonexistent")))
    assert len(specs) == 2
    assert sorted(str(s["key"]["options"]) for s in specs) == ["None", "{'a': 1}"]
    assert all(s["hash"] == key_hash(s["key"]) for s in specs)


class _Store:
    def __init__(self) -> None:
        self.rows: dict[str, dict] = {}

    def optimum_done(self, h: str) -> bool:
        return h in self.rows

    def append_optimum(self, row: dict) -> None:
        self.rows[row["hash"]] = row

    def optimum_row(self, h: str) -> dict | None:
        return self.rows.get(h)


def _resolve_from_table(specs, monkeypatch) -> _Store:
    """``resolve`` with no solver and no cache: what the shipped table answers."""
    monkeypatch.setattr(optimum_table, "solver_unavailable", lambda: "no solver in this test")
    store = _Store()
    resolve(specs, store, executor=None, solve=False)
    return store


@pytest.mark.parametrize("campaign", CAMPAIGNS)
def test_a_looked_up_entry_is_the_episode_asked_for(campaign, monkeypatch):
    specs = episode_specs(episode_jobs(load_campaign(campaign), Path("/nonexistent")))
    store = _resolve_from_table(specs, monkeypatch)
    table = load_table()
    assert store.rows, f"the shipped table answers none of {campaign}'s episodes"
    for spec in specs:
        row = store.rows.get(spec["hash"])
        if row is None:
            continue
        entry = table[row["hash"]]
        assert entry["key"] == spec["key"], f"{campaign}: asked for {spec['key']}, the table's entry is {entry['key']}"
        assert entry["hash"] == key_hash(entry["key"]) == spec["hash"]
        assert row["j_star"] == entry["j_star"] and row["source"] == "table"


def test_an_episode_with_other_options_is_not_its_neighbours(monkeypatch):
    job = episode_jobs(load_campaign("air-bearing"), Path("/nonexistent"))[0]
    assert _resolve_from_table(episode_specs([job]), monkeypatch).rows  # the option-less episode is in the table
    pushed = episode_specs([{**job, "options": {"a": 1}}])
    assert pushed[0]["key"]["options"] == {"a": 1}
    assert _resolve_from_table(pushed, monkeypatch).rows == {}


def test_a_sensor_fault_shares_the_key_of_its_fault_free_episode():
    """The oracle knows the true state: a sensor fault changes neither its problem nor its
    replay's cost, so the cell with one looks up the fault-free episode's J*; an actuator
    fault beside it stays in the key."""
    flight = {**KWARGS, "conditions": "flight"}
    gyro = {"kind": "bias", "target": "sensor", "sensor": "gyro", "index": 2, "value": 1e-3, "onset_s": 5.0}
    wheel = {"kind": "outage", "target": "actuator", "index": 2, "onset_s": 2.0}
    plain = key_hash(episode_key(ENV, flight, 3, None))
    assert key_hash(episode_key(ENV, {**flight, "faults": [gyro]}, 3, None)) == plain
    with_wheel = key_hash(episode_key(ENV, {**flight, "faults": [wheel]}, 3, None))
    assert with_wheel != plain
    assert key_hash(episode_key(ENV, {**flight, "faults": [gyro, wheel]}, 3, None)) == with_wheel
    assert optimum_table.oracle_kwargs({**flight, "faults": [gyro, wheel]}) == {**flight, "faults": [wheel]}
