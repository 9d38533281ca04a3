"""A campaign's report.md opens with its results; the run record (provenance) comes last."""

from experiments.report.leaderboards import leaderboards
from experiments.report.markdown import report_markdown


def test_report_opens_with_the_results_and_ends_with_the_run_record():
    rows = [
        {"env": "rw", "scenario": "s", "fault": "none", "agent": a, "seed": s, "J": j * (1 + 0.1 * s), "success": True}
        for a, j in (("lqr", 10.0), ("pid", 20.0))
        for s in range(5)
    ]
    metadata = {
        "campaign": "tiny",
        "git_revision": "abc123",
        "seeds": [0, 1, 2, 3, 4],
        "executor": "local-pool[1]",
        "wall_time_s": 1.5,
        "success_criteria": {"rw": "final attitude error ≤ 2°"},
    }
    text = report_markdown(rows, leaderboards(rows), metadata, {"J per agent": "figures/leaderboard.png"}, ["a note"])
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    assert headings == ["## Leaderboards", "## Notes", "## Figures", "## Reading the leaderboards", "## Run record"]
    assert text.startswith("# Benchmark report: tiny\n")
    results, record = text.split("## Run record")
    assert "| 1 | lqr | 5 |" in results and "![J per agent](figures/leaderboard.png)" in results
    for line in (
        "| git_revision | abc123 |",
        "| executor | local-pool[1] |",
        "| success: rw | final attitude error ≤ 2° |",
    ):
        assert line in record and line not in results
    assert "success: the env's criterion in the run record" in results
