"""Training progress: a bar with ETA on a terminal, status lines otherwise (:mod:`experiments.progress`)."""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback

from experiments.progress import Progress


class ProgressCallback(BaseCallback):
    """Reports ``model.num_timesteps`` out of ``total`` env steps (from the resumed step on).

    ``bar``: True a tqdm bar, False status lines (e.g. from parallel campaign workers, whose
    bars would overwrite each other), None a bar exactly on a terminal."""

    def __init__(self, total: int, desc: str, bar: bool | None = None) -> None:
        super().__init__()
        self.total = int(total)
        self.desc = desc
        self.bar = bar
        self.progress: Progress | None = None

    def _on_training_start(self) -> None:
        if self.progress is None:  # train() calls learn() once per segment: one progress for the whole run
            self.progress = Progress(self.total, self.desc, "steps", initial=self.model.num_timesteps, bar=self.bar)

    def _on_step(self) -> bool:
        self.progress.update_to(min(self.num_timesteps, self.total))
        return True

    def _on_training_end(self) -> None:
        self.progress.update_to(min(self.num_timesteps, self.total))

    def close(self) -> None:
        """End the bar (or write the last status line); train() calls it after its last segment."""
        if self.progress is not None:
            self.progress.close()
