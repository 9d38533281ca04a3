"""Stable-Baselines3 glue: algorithm registry, Zoo-format hyperparameters, callbacks, training with resume."""

from experiments.training.hyperparams import load_hyperparams
from experiments.training.registry import ALGORITHMS, algorithm_class

__all__ = ["ALGORITHMS", "algorithm_class", "load_hyperparams"]
