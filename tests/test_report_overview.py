"""The cross-plant overview on tiny synthetic campaigns: which controllers it picks, its table,
the page markers, the figures and (with rliable) the aggregates."""

import csv
import sys

import numpy as np
import pytest

from experiments.report import overview as ov

COLUMNS = [
    "env",
    "scenario",
    "fault",
    "agent",
    "train_seed",
    "seed",
    "J",
    "terminated",
    "success",
    "j_star",
    "j_star_source",
    "j_star_metric",
    "j_star_terminated",
    "j_star_final_error_deg",
]

#: agent → (factor on J*, training seeds or None)
AGENTS = {"zero": (50.0, None), "lqr": (1.1, None), "pid": (2.0, None), "ppo": (1.3, (0, 1)), "q-lqr": (1.2, None)}


def _write_plant(root, plant: str, env: str, faults=("none", "stuck"), seeds=range(6)) -> None:
    """``root/plant/episodes.csv``: J* 10 + seed (seed 0's J* replay off by 5°: J* fails there)."""
    rows = []
    for fault in faults:
        for agent, (factor, train_seeds) in AGENTS.items():
            for train_seed in train_seeds or (None,):
                for seed in seeds:
                    j_star = 10.0 + seed
                    wobble = 1.0 + 0.02 * ((seed * 7 + (train_seed or 0) * 3) % 5)
                    rows.append(
                        {
                            "env": env,
                            "scenario": "s",
                            "fault": fault,
                            "agent": agent,
                            "train_seed": "" if train_seed is None else train_seed,
                            "seed": seed,
                            "J": j_star * factor * wobble,
                            "terminated": False,
                            "success": agent != "zero",
                            "j_star": j_star,
                            "j_star_source": "table",
                            "j_star_metric": "final_error_deg",
                            "j_star_terminated": False,
                            "j_star_final_error_deg": 5.0 if seed == 0 else 0.1,
                        }
                    )
    (root / plant).mkdir(parents=True)
    with (root / plant / "episodes.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)


@pytest.fixture
def campaigns(tmp_path):
    _write_plant(tmp_path, "alpha", "a")
    _write_plant(tmp_path, "beta", "b", faults=("none",))
    return tmp_path


def test_rows_are_typed_and_agents_classified_from_what_they_carry(campaigns):
    plant = ov.load_plant("alpha", campaigns)
    row = plant.rows[0]
    assert isinstance(row["J"], float) and row["terminated"] is False and row["fault"] == "none"
    assert {r["train_seed"] for r in plant.rows if r["agent"] == "lqr"} == {None}
    assert plant.learned == {"ppo"} and plant.drift == {"zero"}  # no campaign: q-lqr looks analytic


def test_best_analytic_and_best_learned(campaigns):
    cells = ov.overview_cells([ov.load_plant("alpha", campaigns), ov.load_plant("beta", campaigns)])
    assert [(c.plant, c.cell) for c in cells] == [
        ("alpha", ("a", "s", "none")),
        ("alpha", ("a", "s", "stuck")),
        ("beta", ("b", "s", "none")),
    ]
    for c in cells:
        assert c.analytic["agent"] == "lqr" and c.learned["agent"] == "ppo"
        assert c.oracle["success_rate"] == pytest.approx(5 / 6)  # J* misses the 2° criterion on seed 0
    # the Q-learning LQR is learned when the campaign says so (policy: q-learning-lqr): it beats ppo
    plant = ov.load_plant("beta", campaigns)
    plant.learned.add("q-lqr")
    (cell,) = ov.overview_cells([plant])
    assert cell.analytic["agent"] == "lqr" and cell.learned["agent"] == "q-lqr"
    # free drift is never a pick, even when it is the only other agent
    only = ov.Plant("beta", [r for r in plant.rows if r["agent"] in ("zero", "ppo")], {"ppo"}, {"zero"})
    (cell,) = ov.overview_cells([only])
    assert cell.analytic is None and cell.learned["agent"] == "ppo"


def test_leaderboard_table(campaigns):
    cells = ov.overview_cells([ov.load_plant("alpha", campaigns), ov.load_plant("beta", campaigns)])
    table = ov.leaderboard_table(cells)
    lines = table.splitlines()
    assert lines[0] == (
        "| plant | env · scenario · fault | J* success | best analytic | ΣJ / ΣJ* [95 % CI] "
        "| best learned | ΣJ / ΣJ* [95 % CI] |"
    )
    body = [line for line in lines[2:] if line.startswith("|")]
    assert len(body) == 3
    first = [c.strip() for c in body[0].strip("|").split("|")]
    assert first[0] == "[alpha](campaigns/alpha/report.md)" and first[1] == "a · s · none" and first[2] == "83 %"
    assert first[3] == "lqr" and first[5] == "ppo (2 training seeds × 6 episodes)"
    assert first[4].startswith("1.1") and "[" in first[4] and "[" in first[6]
    assert body[1].startswith("|  |")  # the plant named once
    assert "| zero" not in table and "Best: the first of its kind" in ov.LEADERBOARD_LEGEND


def test_paste_between_markers():
    page = f"# T\n\nintro\n\n{ov.MARK_START}\nold\n{ov.MARK_END}\n\n## rest\n"
    out = ov.paste_between_markers(page, "new table\n")
    assert out == f"# T\n\nintro\n\n{ov.MARK_START}\nnew table\n{ov.MARK_END}\n\n## rest\n"
    assert ov.paste_between_markers(out, "new table\n") == out
    with pytest.raises(ValueError, match="markers"):
        ov.paste_between_markers("# no markers\n", "x")


def test_write_overview_without_aggregates(campaigns, tmp_path):
    page = tmp_path / "docs" / "benchmarks.md"
    page.parent.mkdir()
    page.write_text(f"# B\n\n{ov.MARK_START}\n{ov.MARK_END}\n\nthe rest stays\n")
    written = ov.write_overview(campaigns, page, tmp_path / "docs" / "figures", ("alpha", "beta"), aggregate=False)
    text = page.read_text()
    assert written["ratios"].is_file() and "profiles" not in written
    assert "![J / J* per controller and plant](figures/overview-ratios.png)" in text
    assert text.endswith("the rest stays\n") and "| best learned |" in text


def test_task_scores_are_the_normalized_scores_per_task(campaigns):
    cells = ov.overview_cells([ov.load_plant("alpha", campaigns), ov.load_plant("beta", campaigns)])
    scores = ov.task_scores(cells)
    assert list(scores) == [ov.BEST_ANALYTIC, ov.BEST_LEARNED, "lqr", "pid", "ppo", "q-lqr"]  # zero: no controller
    assert len(scores[ov.BEST_LEARNED]) == 3 and len(scores[ov.BEST_LEARNED][0]) == 12  # 2 training seeds × 6
    assert np.all((scores["pid"][0] > 0.4) & (scores["pid"][0] <= 0.5))  # J* / J of J = 2 J* (× 1 … 1.08)
    rows = [{"J": 4.0, "j_star": 2.0}, {"J": float("inf"), "j_star": 2.0}, {"J": 1.0, "j_star": float("nan")}]
    assert list(ov.normalized_scores(rows)) == [0.5, 0.0]


def test_aggregates_say_how_to_install_rliable_when_it_is_missing(monkeypatch, campaigns):
    monkeypatch.setitem(sys.modules, "rliable", None)
    cells = ov.overview_cells([ov.load_plant("alpha", campaigns)])
    with pytest.raises(ImportError, match=r"\.\[rliable\]"):
        ov.aggregates(ov.task_scores(cells), n_boot=50)


def test_aggregates_with_rliable(campaigns, tmp_path):
    pytest.importorskip("rliable.metrics")
    cells = ov.overview_cells([ov.load_plant("alpha", campaigns), ov.load_plant("beta", campaigns)])
    scores = ov.task_scores(cells)
    agg = ov.aggregates(scores, n_boot=200)
    again = ov.aggregates(scores, n_boot=200)  # seeded: reproducible
    assert agg["tasks"] == 3 and agg["improvement"] == again["improvement"]
    assert all(a["iqm"] == again["algorithms"][k]["iqm"] for k, a in agg["algorithms"].items())
    for name, a in agg["algorithms"].items():
        point, lo, hi = a["iqm"]
        assert lo <= point <= hi, name
        profile, p_lo, p_hi = a["profile"]
        assert profile[0] == 1.0 and np.all(np.diff(profile) <= 0) and np.all((p_lo <= profile) & (profile <= p_hi))
    assert agg["algorithms"]["lqr"]["iqm"][0] == pytest.approx(agg["algorithms"][ov.BEST_ANALYTIC]["iqm"][0])
    p, lo, hi = agg["improvement"]
    assert p == 0.0 and lo == hi == 0.0  # ppo (1.3 J*) never beats the LQR (≤ 1.19 J*)
    same = ov.aggregates({ov.BEST_ANALYTIC: scores["lqr"], ov.BEST_LEARNED: scores["lqr"]}, n_boot=50)
    assert same["improvement"][0] == 0.5  # identical runs: a tie
    # equal to floating-point noise is a tie too, not a win for the one 1e-14 ahead
    noisy = [s * (1 + 1e-14) for s in scores["lqr"]]
    nudged = ov.aggregates({ov.BEST_ANALYTIC: scores["lqr"], ov.BEST_LEARNED: noisy}, n_boot=50)
    assert nudged["improvement"][0] == 0.5
    ahead = [np.minimum(s * (1 + 1e-6), 1.0) for s in scores["lqr"]]
    assert ov.aggregates({ov.BEST_ANALYTIC: scores["lqr"], ov.BEST_LEARNED: ahead}, n_boot=50)["improvement"][0] > 0.5
    assert "P(best learned > best analytic) = 0.000" in ov.aggregates_table(agg)
    png = ov.plot_profiles(agg, tmp_path / "profiles.png")
    assert png.is_file() and png.stat().st_size > 0
    # the result first: the table and both figures, then what the columns mean, then the aggregates
    text = ov.overview_markdown(cells, agg, "figures")
    order = [
        text.index("| plant | env · scenario · fault"),
        text.index("overview-ratios.png"),
        text.index("overview-profiles.png"),
        text.index("J* success: the share"),
        text.index("IQM of J* / J [95 % CI]"),
    ]
    assert order == sorted(order)
