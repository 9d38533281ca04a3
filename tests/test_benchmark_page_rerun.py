"""benchmarks/page_rerun.py: a rerun's rows against the committed pages'."""

from __future__ import annotations

import csv
import json

import pytest

from benchmarks import page_rerun

FIELDS = ["env", "scenario", "fault", "agent", "train_seed", "seed", "J", "j_star"]


def _page(folder, rows, wall_s=None):
    folder.mkdir(parents=True)
    with (folder / "episodes.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        w.writerows(rows)
    if wall_s is not None:
        events = [{"event": "start", "run": "a"}, {"event": "end", "run": "a", "wall_time_s": wall_s}]
        (folder / "runs.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))


def test_rows_are_compared_episode_by_episode(tmp_path):
    committed = [
        ("rw", "s", "none", "lqr", "", "0", 2.0, 1.0),
        ("rw", "s", "none", "lqr", "", "1", 4.0, 2.0),
        ("rw", "s", "none", "ppo", "0", "0", 3.0, 1.0),
        ("rw", "s", "none", "gone", "", "0", 1.0, 1.0),
    ]
    rerun = [
        ("rw", "s", "none", "lqr", "", "0", 2.0, 1.0),
        ("rw", "s", "none", "lqr", "", "1", 4.0, 2.0),
        ("rw", "s", "none", "ppo", "0", "0", 2.7, 1.0),
        ("rw", "s", "none", "new", "", "0", 1.0, 1.0),
    ]
    _page(tmp_path / "pages" / "wheel", committed)
    _page(tmp_path / "all" / "wheel", rerun, wall_s=120.0)
    _page(tmp_path / "all" / "slew", rerun, wall_s=60.0)  # no committed page: named, not compared
    result = page_rerun.main(
        ["--rerun", str(tmp_path / "all"), "--pages", str(tmp_path / "pages"), "--out", str(tmp_path / "r.json")]
    )
    page = result["pages"]["wheel"]
    rows = {r["agent"]: r for r in page["rows"]}
    assert rows["lqr"]["max_relative_dj"] == 0.0 and not rows["lqr"]["learned"]
    assert rows["lqr"]["page_j_over_j_star"] == rows["lqr"]["rerun_j_over_j_star"] == 2.0
    assert rows["ppo"]["learned"]
    assert rows["ppo"]["max_relative_dj"] == pytest.approx(0.1)
    assert rows["ppo"]["rerun_j_over_j_star"] == pytest.approx(2.7)
    assert page["only_page"] == ["rw/s/none/gone"] and page["only_rerun"] == ["rw/s/none/new"]
    assert result["summary"] == [
        {
            "page": "wheel",
            "wall_min": 2.0,
            "analytic_rows": 1,
            "analytic_repeated": 1,
            "analytic_repeated_worst": 0.0,
            "analytic_worst": 0.0,
            "learned_rows": 1,
            "learned_repeated": 0,
            "missing_rows": 2,
        }
    ]
    assert result["pages_only_rerun"] == ["slew"] and result["pages_only_committed"] == []
    assert json.loads((tmp_path / "r.json").read_text())["summary"] == result["summary"]


def test_a_row_missing_episodes_or_with_no_finite_j_does_not_count_as_repeated(tmp_path):
    committed = [
        ("rw", "s", "none", "lqr", "", "0", 2.0, 1.0),
        ("rw", "s", "none", "lqr", "", "1", 4.0, 2.0),
        ("rw", "s", "none", "pid", "", "0", 1.0, 1.0),
        ("rw", "s", "none", "mpc", "", "0", "nan", 1.0),
    ]
    rerun = [
        ("rw", "s", "none", "lqr", "", "0", 2.0, 1.0),
        ("rw", "s", "none", "pid", "", "5", 1.0, 1.0),
        ("rw", "s", "none", "mpc", "", "0", 1.0, 1.0),
    ]
    _page(tmp_path / "pages" / "wheel", committed)
    _page(tmp_path / "all" / "wheel", rerun)  # no runs.jsonl: its minutes are unknown
    result = page_rerun.main(
        ["--rerun", str(tmp_path / "all"), "--pages", str(tmp_path / "pages"), "--out", str(tmp_path / "r.json")]
    )
    rows = {r["agent"]: r for r in result["pages"]["wheel"]["rows"]}
    assert rows["lqr"]["max_relative_dj"] == 0.0 and rows["lqr"]["episodes_only_page"] == 1
    assert (
        rows["pid"]["episodes"] == 0
        and rows["pid"]["max_relative_dj"] is None
        and rows["pid"]["page_j_over_j_star"] is None
    )
    assert rows["mpc"]["max_relative_dj"] is None
    assert not any(page_rerun.repeated(r) for r in rows.values())
    summary = result["summary"][0]
    assert summary["wall_min"] is None and summary["analytic_repeated"] == 0 and summary["analytic_worst"] is None
    json.loads((tmp_path / "r.json").read_text(), parse_constant=lambda c: pytest.fail(f"not strict JSON: {c}"))


def test_a_rerun_without_a_committed_page_is_refused(tmp_path):
    _page(tmp_path / "all" / "wheel", [("rw", "s", "none", "lqr", "", "0", 1.0, 1.0)], wall_s=1.0)
    (tmp_path / "pages").mkdir()
    with pytest.raises(SystemExit, match="no page of"):
        page_rerun.main(
            ["--rerun", str(tmp_path / "all"), "--pages", str(tmp_path / "pages"), "--out", str(tmp_path / "r.json")]
        )
