"""Shared check of the batched envs' tests: one batched step against the single envs."""

from __future__ import annotations

import numpy as np


def step_matches_singles(vec, singles, actions) -> tuple[np.ndarray, np.ndarray, dict, list[dict]]:
    """Step ``vec`` and every single env with the same actions and assert that each row is
    bitwise the single env's (observation, reward, flags, applied torque: ``truth`` of
    :mod:`attitude_envs.info`). Returns
    ``(terminated, truncated, batched infos, single infos)`` for env-specific checks."""
    obs, rewards, term, trunc, infos = vec.step(actions)
    single_infos = []
    for i, s in enumerate(singles):
        o, r, te, tr, info = s.step(actions[i])
        assert np.array_equal(obs[i], o) and rewards[i] == r and te == term[i] and tr == trunc[i]
        assert np.array_equal(infos["truth"]["applied"][i], info["truth"]["applied"])
        single_infos.append(info)
    return term, trunc, infos, single_infos
