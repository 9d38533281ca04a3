"""JAX training: the same task and recipe on SB3, SBX and the fused JAX PPO trainer
(:mod:`agents.fused_ppo`, ``train(backend="jax")``), speed and quality side by side.

``python -m benchmarks.jax_training [--quick] [--rounds R] [--seeds S] [--skip-quality]
[--skip-search] [--skip-stepping] [--no-all-cores] [--speed-env ID ...] [--out DIR]`` prints a
markdown summary and writes ``DIR/jax_training.json`` (default ``results/benchmarks/``,
git-ignored; the committed numbers: ``--out benchmarks/results``). The task is a campaign
agent's: PPO on AirBearing-v1 (``experiments/training/hyperparams/ppo.yml``, 120 k env steps) with the
kwargs the ``air-bearing`` campaign trains it with, scored on that campaign's cell (AirBearing-v0's
regulation episodes, seeds 0–19) against J* from ``experiments/optimum_table.json``. Sections
(each row states its unit and what was pinned):

* ``speed``: env steps/s of training (rollouts and PPO updates, no evaluation) of SB3 and SBX on
  the native batched env (as ``train`` builds them) and of the fused trainer for one seed (the
  program ``train`` compiles) and for 16 ``jax.vmap``-ped seeds (aggregate steps/s, all seeds
  together). After a warm-up (compilation excluded, reported in ``compile``) the four alternate
  in ``--rounds`` rounds of equal env steps per seed, so that machine noise hits all alike; rows
  give the median and [min, max] of the rounds, ratios the median of the per-round ratios with
  their [min, max]. ``ppo_per_seed_vs_sbx`` = fused 1-seed rate / SBX rate;
  ``ppo_16_seeds_vs_sbx`` = fused 16-seed aggregate rate / SBX's one-seed rate. The process is
  pinned to one CPU (:func:`experiments.processes.pin_to_one_core`, which also sizes JAX's
  thread pool) with ``torch.set_num_threads(1)``, as campaign workers run; ``jax_all_cores``
  repeats the fused rows in a child process on every CPU this process may use (its own rounds;
  its ratios are to the pinned SBX median). ``--speed-env`` adds envs (``speed_other_envs``).
* ``quality``: ``train`` of the recipe with each backend for ``--seeds`` training seeds, each in
  a fresh pinned process (so compilation and jit warm-up count in its wall time: s, from the
  ``train`` call to its return, evaluations and checkpoints included), then each run's best
  snapshot (chosen on the validation seeds 10000–10004, as campaigns do) played on the cell's 20
  episodes by the campaign's episode runner; J / J* = ΣJ / ΣJ* over them (the campaign
  report's ratio). Parity: the fused trainer's mean J/J* over seeds ≤ the worst SBX seed's.
  ``time_to_target``: a twin of each fused run (same seed and program: the same policies)
  evaluates on the cell's 20 episodes instead; the wall time (s since the ``train`` call,
  compilation included) of its first evaluation with J/J* ≤ 1.05 (the evaluations are every
  10 k steps: a ceiling on the time); pinned to one CPU, then again on every CPU this process
  may use (``time_to_target_all_cores``: the issue's target is on 2 cores, and XLA compiles on
  all of them — 7–12 s on 2 cores against 13–20 s on one); ``time_to_target_warm_cache``: the
  twins once more (on every CPU where the all-cores twins ran) with JAX's persistent compilation
  cache, as the command line uses it, filled by one short run of the same program first: what
  every run after a machine's first one takes.
* ``search``: ``attitude-envs tune --backend jax`` with 64 settings at the recipe's budget
  (120 k steps each; ``tune``'s default is 300 k) in a pinned child process: wall s and the best
  setting's eval J (validation seeds 10000+).
* ``env_stepping``: env steps/s (decisions, all envs together) of the JAX AirBearing-v1 and
  ReactionWheel-v1 plants, ``jax.vmap`` over N envs in a jitted ``lax.scan``, against the numba
  batched env at the same N, alternating rounds, pinned; on a GPU also N = 65,536 (ReactionWheel).

Each section is kept in ``OUT/jax_training.partial.json`` as it finishes: a run killed or
failed in a later section, rerun with the same command on the same commit, takes the finished
ones from there (``meta.sections_from_an_earlier_run`` names them) and deletes the file when the
whole run is written.

Compilation comes from JAX's persistent cache only in ``time_to_target_warm_cache`` (a folder of
the run's own, emptied first); it is switched off in this process and every other child.
``--quick`` (tiny budgets, XLA's fast-compile option, 1 seed, 2 rounds: a smoke run of every
code path, not a measurement) takes about 3 min on a quiet 2-core machine; the full run 16–25
min there (about 10 of them the quality section, 6 the search). Nothing
here is asserted: the issue's targets are reported beside what was measured (``targets``).

One module per section, :mod:`~benchmarks.jax_training.speed`, :mod:`~benchmarks.jax_training.quality`,
:mod:`~benchmarks.jax_training.search` and :mod:`~benchmarks.jax_training.stepping`, on the
campaign task of :mod:`~benchmarks.jax_training.task`; :mod:`~benchmarks.jax_training.children`
runs the fresh processes (through :func:`experiments.processes.run_in_child`),
:mod:`~benchmarks.jax_training.summary` compares with the targets and prints the markdown,
:mod:`~benchmarks.jax_training.checkpoint` keeps the finished sections and ``__main__`` is the
command line.
"""
