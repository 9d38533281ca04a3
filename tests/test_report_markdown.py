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


def test_constrained_cells_show_the_failure_rate_cvar_and_what_each_layer_costs():
    from experiments.report.markdown import layers_markdown

    def row(agent, seed, j, j_star, violations, margin):
        key = {"env": "slew", "scenario": "s", "fault": "none", "agent": agent, "seed": seed, "J": j}
        return key | {"j_star": j_star, "violations": violations, "min_margin_deg": margin, "success": True}

    rows = [row("bare", s, 12.0 + s, 10.0, 3 if s == 0 else 0, -4.0 if s == 0 else 6.0) for s in range(10)]
    rows += [row("filtered", s, 13.0 + s, 10.0, 0, 2.0 + s) for s in range(10)]
    boards = leaderboards(rows)
    entry = {e["agent"]: e for e in boards[("slew", "s", "none")]}
    assert entry["bare"]["violating_rate"] == 0.1 and entry["bare"]["violation_steps"] == 0.3
    assert entry["bare"]["min_margin_deg"] == -4.0 and entry["filtered"]["violating_rate"] == 0.0
    assert entry["bare"]["J_over_J_star_cvar10"] == 2.1  # the worst tenth: seed 9, (12 + 9) / 10
    text = report_markdown(
        rows, boards, {"campaign": "c", "layers": [{"name": "filter", "without": "bare", "with": "filtered"}]}
    )
    assert "| J / J* | CVaR₀.₁ J/J* | success |" in text
    assert "| violating episodes | violation steps | least margin [deg] |" in text
    assert "## What each layer costs" in text
    layer = layers_markdown(rows, boards, [{"name": "filter", "without": "bare", "with": "filtered"}])
    cost = (sum(13.0 + s for s in range(10)) / sum(12.0 + s for s in range(10)) - 1) * 100
    assert f"| filter | bare | 1.6500 | 10 % | filtered | 1.7500 | 0 % | +{cost:.1f} % |" in layer
    assert "What each layer costs" not in report_markdown(rows, boards, {"campaign": "c"})
