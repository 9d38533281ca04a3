"""One syntax for episode and training seeds, everywhere (command line and campaign YAML).

=================  ==============================  ======================
written            means                           seeds
=================  ==============================  ======================
``5`` (a count)    the first five seeds            0, 1, 2, 3, 4
``10-14``          an inclusive range              10, 11, 12, 13, 14
``0,3,7-8``        a list of seeds and ranges      0, 3, 7, 8
``[0, 3, 7]``      a YAML list (campaign files)    0, 3, 7
=================  ==============================  ======================

A single seed ``k`` is the range ``k-k``. Seeds are distinct integers in [0, :data:`MAX_SEED`],
at most :data:`MAX_COUNT` of them (a count such as ``100000000`` is refused at once: at about a
second an episode it would run for years, and its job list alone would take minutes to build).
"""

from __future__ import annotations

import argparse
from typing import Any

#: the largest seed (numpy's and the batched envs' seeds are 32-bit)
MAX_SEED = 2**31 - 1
#: the most seeds one list may hold (episodes per cell)
MAX_COUNT = 100_000
#: Training envs draw their episodes from seeds in [TRAINING_SEED_BASE, MAX_SEED]: training seed
#: ``s`` seeds sub-env ``i`` with ``TRAINING_SEED_BASE + s·TRAINING_SEED_STRIDE + i`` (mod the
#: range), so no training episode starts where an evaluation episode (seeds 0, 1, …) or a
#: validation episode (seeds 10000+) of the same env starts. Episode seeds at or above the base are
#: accepted but share the training stream.
TRAINING_SEED_BASE = 2**30
#: the most sub-envs one training run may hold without overlapping the next training seed's
TRAINING_SEED_STRIDE = 2**12
SYNTAX = "a count N (seeds 0..N-1), a range A-B, or a comma list like 0,3,7-9"
LIMITS = f"seeds distinct, in [0, {MAX_SEED}], at most {MAX_COUNT} of them"


def _bad(name: str, value: Any, why: str) -> ValueError:
    return ValueError(f"{name} must be {SYNTAX} ({LIMITS}): {why}, got {_short(value)}")


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else f"{text[:60]}... ({len(text)} characters)"


def _check_size(name: str, value: Any, count: int, largest: int) -> None:
    """Before a list is built: at most :data:`MAX_COUNT` seeds, none above :data:`MAX_SEED`."""
    if count > MAX_COUNT:
        raise _bad(name, value, f"{count} seeds is more than {MAX_COUNT}")
    if largest > MAX_SEED:
        raise _bad(name, value, f"seed {largest} is above {MAX_SEED}")


def _items(name: str, text: str) -> list[int]:
    seeds: list[int] = []
    for part in text.split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi) if sep else None
        except ValueError:
            raise _bad(name, text, f"{part!r} is not an integer or a range") from None
        if b is None:
            _check_size(name, text, len(seeds) + 1, a)
            seeds.append(a)
        elif b < a:
            raise _bad(name, text, f"range {part!r} runs backwards")
        else:
            _check_size(name, text, len(seeds) + b - a + 1, b)
            seeds.extend(range(a, b + 1))
    return seeds


def parse_seeds(value: Any, name: str = "seeds") -> list[int]:
    """The list of seeds ``value`` stands for (see the module's table); ``name`` is the parameter
    the error message names (``--seeds``, ``agents[0].train.seeds``). Raises ``ValueError``."""
    if isinstance(value, bool):
        raise _bad(name, value, "a boolean is not a seed")
    if isinstance(value, int):
        if value < 1:
            raise _bad(name, value, "a count must be >= 1")
        _check_size(name, value, value, value - 1)
        return list(range(value))
    if isinstance(value, list | tuple):
        if not value or not all(isinstance(s, int) and not isinstance(s, bool) for s in value):
            raise _bad(name, value, "a list must hold at least one integer and only integers")
        seeds = [int(s) for s in value]
        _check_size(name, value, len(seeds), max(seeds))
    elif isinstance(value, str):
        text = value.strip()
        if not text:
            raise _bad(name, value, "it is empty")
        if text.isdigit():
            return parse_seeds(int(text), name)
        seeds = _items(name, text)
    else:
        raise _bad(name, value, f"a {type(value).__name__} is not a seed list")
    if min(seeds) < 0:
        raise _bad(name, value, "seeds must be >= 0")
    if len(set(seeds)) != len(seeds):
        raise _bad(name, value, "a seed appears twice")
    return seeds


def training_env_seed(seed: int) -> int:
    """The seed of sub-env 0 of training seed ``seed``'s training env (sub-env ``i`` takes this
    ``+ i``, SB3's convention): in the training stream, disjoint from evaluation and validation
    seeds (:data:`TRAINING_SEED_BASE`)."""
    span = MAX_SEED + 1 - TRAINING_SEED_BASE
    return TRAINING_SEED_BASE + (int(seed) * TRAINING_SEED_STRIDE) % (span - TRAINING_SEED_STRIDE)


def seeds_arg(text: str) -> list[int]:
    """An argparse ``type`` for ``--seeds``: :func:`parse_seeds` with argparse's one-line error
    (``argument --seeds: must be a count N ...``)."""
    try:
        return parse_seeds(text, "seeds")
    except ValueError as exc:  # argparse names the option itself
        raise argparse.ArgumentTypeError(str(exc).removeprefix("seeds ")) from None
