"""Campaign report: leaderboards (J mean, 95 % bootstrap CI, IQM), paper metrics, plots, metadata.

Statistics are over episodes (evaluation seeds × training seeds) of one agent in one
env × scenario × fault cell: the mean of J with a percentile bootstrap 95 % confidence
interval (:func:`scipy.stats.bootstrap`, ``n_boot`` resamples, a seeded generator, so the report
is reproducible) and the
interquartile mean (mean of the middle 50 %, ``scipy.stats.trim_mean(J, 0.25)``; Agarwal
et al. 2021). A cell with fewer than ``MIN_EPISODES`` episodes is flagged; a cell whose
episodes all have the same J (a deterministic agent from a fixed start) has no CI: the
report prints "deterministic". Success is per env, stated in the report
(:func:`experiments.campaign.episode.success_criterion`). An agent's ``note`` is shown beside
it in the leaderboards.

One module per job, imported downwards in this order: :mod:`~experiments.report.statistics`
(bootstrap CI, IQM, J / J*), :mod:`~experiments.report.leaderboards` (the ranked cells, J*'s own
line, which agents a report shows), :mod:`~experiments.report.markdown` (tables and the report
text), :mod:`~experiments.report.provenance` (what ran, where, from which code and training
runs), :mod:`~experiments.report.figures` (plots, time histories, the episode video) and
:mod:`~experiments.report.writing` (``report.md``, ``leaderboard.json``, ``metadata.json``,
``index.md``). Beside them, :mod:`~experiments.report.overview` reads the committed plant
campaigns' ``episodes.csv`` and writes the cross-plant overview of ``docs/benchmarks.md`` (one
leaderboard, J / J* per controller, and rliable's aggregates with the optional extra ``rliable``).
"""
