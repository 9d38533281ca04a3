"""Training agents on the suite's envs: Stable-Baselines3, SBX and the fused JAX PPO trainer as
backends of one ``train`` (:mod:`experiments.training.training`), with Zoo-format
hyperparameters, exact-resume checkpoints, evaluation on the shared cost J and hyperparameter
searches. The algorithm and backend are parsed once into an
:class:`~experiments.training.algorithm.Algorithm`."""
