"""``benchmarks/onset_bound.py``: the cells' episodes come from their campaign YAML, and one
episode's hedging front starts at the nominal optimum's prefix (J*_onset, the nominal J*) and
ends at J*'s (J*, the nominal episode after J*'s preparation)."""

from __future__ import annotations

import pytest

from benchmarks import onset_bound as ob


def test_cell_episodes_pair_the_fault_cell_with_its_nominal_cell():
    (episode,) = ob.cell_episodes("wheel/two-wheel-failure", [3])
    fault_kwargs, _ = episode["fault"]
    nominal_kwargs, _ = episode["nominal"]
    assert episode["seed"] == 3 and episode["onset_s"] == 2.0
    assert [f["index"] for f in fault_kwargs["faults"]] == [0, 1]
    assert "faults" not in nominal_kwargs
    assert {k: v for k, v in fault_kwargs.items() if k != "faults"} == nominal_kwargs
    with pytest.raises(ValueError, match="fault must be one of"):
        ob.cell_episodes("wheel/none", [0])
    with pytest.raises(ValueError, match=r"seeds \[25\] are not seeds"):
        ob.cell_episodes("wheel/two-wheel-failure", [25])
    with pytest.raises(SystemExit):  # argparse's error: the message names --blends
        ob.main(["--blends", "x"])


def test_one_episode_front_runs_from_the_nominal_prefix_to_the_oracles(tmp_path, monkeypatch):
    pytest.importorskip("casadi")
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))
    (episode,) = ob.cell_episodes("wheel/two-wheel-failure", [3])
    row = ob.onset_bound(episode, blends=(0.0, 1.0))
    assert row["fixed_decisions"] == 20  # 2 s at the cell's 0.1 s
    first, last = row["front"]
    assert first["nominal"]["J"] == row["j_star_nominal"] and last["fault"]["J"] == row["j_star"]
    # holding a prefix can only cost: each continuation is at least its episode's optimum
    assert row["j_star_onset"] == first["fault"]["J"] >= row["j_star"] * (1 - 1e-9)
    # seed 3 is one where J*'s preparation matters (1.79 × J* without it): a prefix that is not
    # held would let the solver prepare and give J* back
    assert row["j_star_onset"] > 1.5 * row["j_star"]
    assert last["nominal"]["J"] >= row["j_star_nominal"] * (1 - 1e-9)
    assert first["fault"]["status"] == "Solve_Succeeded" and not first["fault"]["terminated"]


def test_an_interrupted_run_resumes_from_its_journal(tmp_path, monkeypatch):
    """Each finished episode is journaled next to --out; --resume solves only the others, and a
    journal line cut short by a kill is ignored."""
    solved = []

    def fake_bound(episode, blends):
        solved.append(episode["seed"])
        if episode["seed"] == 2 and len(solved) == 3:
            raise KeyboardInterrupt  # killed while solving the third episode
        j = 1.0 + episode["seed"]
        front = [{"blend": w, "fault": {"J": 2 * j}, "nominal": {"J": j}} for w in blends]
        return {"seed": episode["seed"], "j_star": j, "j_star_nominal": j, "front": front}

    monkeypatch.setattr(ob, "onset_bound", fake_bound)
    out = tmp_path / "bound.json"
    argv = ["--cells", "wheel/two-wheel-failure", "--seeds", "0-2", "--blends", "0,1", "--out", str(out)]
    with pytest.raises(KeyboardInterrupt):
        ob.main(argv)
    journal = out.with_suffix(".journal.jsonl")
    with journal.open("a") as fh:
        fh.write('{"key": "cut sho')  # a kill in the middle of a line
    assert solved == [0, 1, 2] and not out.exists()
    ob.main([*argv, "--resume"])
    assert solved == [0, 1, 2, 2]  # only the unfinished episode is solved again
    assert sorted(ob.read_journal(journal)) and len(ob.read_journal(journal)) == 3
    with pytest.raises(SystemExit):  # --resume without --out
        ob.main(["--resume"])
