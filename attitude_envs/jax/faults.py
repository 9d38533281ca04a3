"""The suite's actuator faults (:mod:`attitude_envs.faults`) as arrays, for the JAX plants.

An episode's realized faults are a :class:`FaultParams` of fixed length ``F`` (padded with
kind 0, no fault), applied in their order exactly as :meth:`attitude_envs.faults.ActuatorFaults.apply`
composes them: each active fault rewrites its actuator's output in turn, ``saturation``
lowers that actuator's limit, and the result is clipped to the limits. A ``stuck`` fault
latches the output it sees at its first active step (or holds its ``value``) and releases
it when it ends; an ``intermittent`` fault switches on/off after exponential dwell times
drawn from the step's key (the numba envs draw them from numpy's generator: the same law,
not the same draws). Both keep their runtime state in :class:`FaultState`.

:func:`from_realized` copies a numba env's realized faults (the equality tests and
:func:`attitude_envs.jax.make`'s episodes); :func:`realize` draws them in JAX from the
suite's fault dicts, so ``jax.vmap`` over keys randomizes faults per env.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from attitude_envs.faults import KIND_CODES, RealizedFault, define_effect, validate_fault
from attitude_envs.jax.ops import JAX

_STUCK, _SAT, _INTER = KIND_CODES["stuck"], KIND_CODES["saturation"], KIND_CODES["intermittent"]
_effect = define_effect(JAX)
#: breakpoints kept of an ``effectiveness`` schedule (padded by repeating the last one)
SCHEDULE_POINTS = 8


@struct.dataclass
class FaultParams:
    """``F`` realized faults: per fault its ``kind`` code, actuator ``index``, ``value``
    (``has_value`` False: a stuck fault that latches the command), ``onset`` and ``end`` (s;
    end inf: permanent), ``effectiveness`` schedule (``schedule_t`` s, ``schedule_e``;
    ``has_schedule``) and intermittent dwell means (s)."""

    kind: jax.Array
    index: jax.Array
    value: jax.Array
    has_value: jax.Array
    onset: jax.Array
    end: jax.Array
    schedule_t: jax.Array
    schedule_e: jax.Array
    has_schedule: jax.Array
    mean_on: jax.Array
    mean_off: jax.Array

    @property
    def n_faults(self) -> int:
        return int(self.kind.shape[-1])


@struct.dataclass
class FaultState:
    """Runtime state per fault: the latched ``held`` value (``holding``), an intermittent
    fault's phase ``on`` and ``next_switch`` time (s)."""

    held: jax.Array
    holding: jax.Array
    on: jax.Array
    next_switch: jax.Array


def no_faults(n_faults: int = 0) -> FaultParams:
    """``n_faults`` padding entries (kind 0)."""
    return from_realized([], n_faults)


def from_realized(realized: list[RealizedFault], n_faults: int | None = None) -> FaultParams:
    """The arrays of a numba env's ``fault_layer.realized`` list, padded to ``n_faults``
    entries (default: its length)."""
    n = len(realized) if n_faults is None else int(n_faults)
    if len(realized) > n:
        raise ValueError(f"n_faults must be >= the {len(realized)} realized faults, got {n_faults}")
    kind = np.zeros(n, np.int32)
    index = np.zeros(n, np.int32)
    value = np.zeros(n)
    has_value = np.zeros(n, bool)
    onset = np.zeros(n)
    end = np.full(n, np.inf)
    sched_t = np.zeros((n, SCHEDULE_POINTS))
    sched_e = np.ones((n, SCHEDULE_POINTS))
    has_sched = np.zeros(n, bool)
    mean_on = np.ones(n)
    mean_off = np.ones(n)
    for j, f in enumerate(realized):
        kind[j] = KIND_CODES[f.kind]
        index[j] = f.index
        has_value[j] = f.value is not None
        value[j] = 0.0 if f.value is None else f.value
        onset[j] = f.onset_s
        end[j] = np.inf if f.duration_s is None else f.onset_s + f.duration_s
        if f.schedule is not None:
            s = np.asarray(f.schedule, dtype=float)
            if len(s) > SCHEDULE_POINTS:
                raise ValueError(
                    f"an effectiveness schedule takes at most {SCHEDULE_POINTS} breakpoints in the JAX plants, got {len(s)}"
                )
            pad = SCHEDULE_POINTS - len(s)
            sched_t[j] = np.concatenate([s[:, 0], s[-1, 0] + np.arange(1, pad + 1)])  # strictly increasing
            sched_e[j] = np.concatenate([s[:, 1], np.full(pad, s[-1, 1])])
            has_sched[j] = True
        mean_on[j], mean_off[j] = f.mean_on_s, f.mean_off_s
    return FaultParams(
        kind=jnp.asarray(kind),
        index=jnp.asarray(index),
        value=jnp.asarray(value),
        has_value=jnp.asarray(has_value),
        onset=jnp.asarray(onset),
        end=jnp.asarray(end),
        schedule_t=jnp.asarray(sched_t),
        schedule_e=jnp.asarray(sched_e),
        has_schedule=jnp.asarray(has_sched),
        mean_on=jnp.asarray(mean_on),
        mean_off=jnp.asarray(mean_off),
    )


def draws_per_episode(config: dict) -> bool:
    """Whether the fault dict ``config`` draws anything per episode: a ``"random"`` index
    (the default when ``index`` is absent) or a ``{"uniform": [a, b]}`` value, onset or
    duration. An env holding such a fault redraws its faults at every reset (the numba
    envs' fault layer does; the JAX plants with :func:`realize`, their ``redraw_faults``)."""
    return config.get("index", "random") == "random" or any(
        isinstance(config.get(key), dict) for key in ("value", "onset_s", "duration_s")
    )


def realize(key: jax.Array, configs: list[dict], n_actuators: int) -> FaultParams:
    """Draw one episode's faults from the suite's fault dicts (validated as the numba envs
    validate them) with ``key``: ``"random"`` indices and ``{"uniform": [a, b]}`` values,
    onsets and durations. ``index: "all"`` expands to one entry per actuator. The array
    length depends only on ``configs`` (so draws for many keys stack and ``vmap``)."""
    entries = []
    for i, c in enumerate(configs or []):
        validate_fault(c, n_actuators, where=f"faults[{i}]")
        if c.get("target", "actuator") != "actuator":
            raise ValueError(f"faults[{i}].target: the JAX plants take actuator faults only, got {c.get('target')!r}")
        idx = c.get("index", "random")
        entries += [(i, c, a) for a in range(n_actuators)] if idx == "all" else [(i, c, idx)]
    n = len(entries)
    base = from_realized([], n)
    keys = jax.random.split(key, (max(n, 1), 4))
    # onset and duration are drawn once per fault dict (shared by the entries of "all"), as
    # the numba layer draws them; index and value per entry
    config_keys = jax.random.split(jax.random.fold_in(key, 1), (max(len(configs or []), 1), 2))

    def draw(spec, k, default):
        if spec is None:
            return jnp.asarray(default, dtype=float)
        if isinstance(spec, dict):
            lo, hi = spec["uniform"]
            return jax.random.uniform(k, (), minval=float(lo), maxval=float(hi), dtype=float)
        return jnp.asarray(float(spec), dtype=float)

    kind, index, value, has_value, onset, end = [], [], [], [], [], []
    st, se, hs, mon, moff = [], [], [], [], []
    for j, (i, c, idx) in enumerate(entries):
        k = keys[j]
        kind.append(KIND_CODES[c["kind"]])
        index.append(jax.random.randint(k[0], (), 0, n_actuators) if idx == "random" else jnp.asarray(int(idx)))
        value.append(draw(c.get("value"), k[1], 0.0))
        has_value.append(c.get("value") is not None)
        o = draw(c.get("onset_s", 0.0), config_keys[i, 0], 0.0)
        onset.append(o)
        end.append(
            o + draw(c["duration_s"], config_keys[i, 1], 0.0)
            if c.get("duration_s") is not None
            else jnp.asarray(jnp.inf)
        )
        sched = from_realized(
            [
                RealizedFault(
                    c["kind"],
                    0,
                    None,
                    0.0,
                    None,
                    None if c.get("schedule") is None else np.asarray(c["schedule"], float),
                )
            ]
        )
        st.append(sched.schedule_t[0])
        se.append(sched.schedule_e[0])
        hs.append(sched.has_schedule[0])
        mon.append(float(c.get("mean_on_s", 1.0)))
        moff.append(float(c.get("mean_off_s", 1.0)))
    if n == 0:
        return base
    return FaultParams(
        kind=jnp.asarray(kind, jnp.int32),
        index=jnp.stack(index).astype(jnp.int32),
        value=jnp.stack(value),
        has_value=jnp.asarray(has_value),
        onset=jnp.stack(onset),
        end=jnp.stack(end),
        schedule_t=jnp.stack(st),
        schedule_e=jnp.stack(se),
        has_schedule=jnp.stack(hs),
        mean_on=jnp.asarray(mon),
        mean_off=jnp.asarray(moff),
    )


def initial_state(key: jax.Array, faults: FaultParams) -> FaultState:
    """The runtime state at an episode's start: nothing latched; intermittent faults off
    until ``onset + Exp(mean_off)`` (the numba layer's first draw)."""
    n = faults.kind.shape[-1]
    dwell = jax.random.exponential(key, (n,), dtype=faults.onset.dtype) if n else jnp.zeros_like(faults.onset)
    first_on = faults.onset + faults.mean_off * dwell  # no faults: no draw (a threefry program to compile)
    return FaultState(
        held=jnp.zeros_like(faults.value),
        holding=jnp.zeros(n, dtype=bool),
        on=jnp.zeros(n, dtype=bool),
        next_switch=first_on,
    )


def active(faults: FaultParams, t_s) -> jax.Array:
    """Per fault, whether it acts at time ``t_s`` (``onset <= t < end``; padding never)."""
    return (faults.kind > 0) & (faults.onset <= t_s) & (t_s < faults.end)


def active_flags(faults: FaultParams, t_s, n_actuators: int) -> jax.Array:
    """1.0 per actuator with an active fault at ``t_s`` (the ``fault_hint`` flags)."""
    on = (faults.index[:, None] == jnp.arange(n_actuators)) & active(faults, t_s)[:, None]
    return jnp.any(on, axis=0).astype(jnp.zeros(0).dtype)  # a mask, not a scatter (see apply)


def apply(
    faults: FaultParams, state: FaultState, key: jax.Array, commanded: jax.Array, t_s, limits: jax.Array
) -> tuple[jax.Array, FaultState]:
    """The outputs the actuators deliver for ``commanded`` at ``t_s`` and the faults' next
    runtime state (:meth:`attitude_envs.faults.ActuatorFaults.apply`, composed in order)."""
    out = jnp.asarray(commanded)
    limit = jnp.broadcast_to(jnp.asarray(limits, dtype=out.dtype), out.shape)
    full = limit
    on, next_switch = _advance_intermittent(faults, state, key, t_s)
    n = faults.kind.shape[-1]
    if n == 0:
        return jnp.clip(out, -limit, limit), FaultState(
            held=state.held, holding=state.holding, on=on, next_switch=next_switch
        )
    # every schedule interpolated at once (one search), then one fault after another in a
    # loop (the compiled program does not grow with the fault count); actuators selected by
    # masks, not scatters (XLA expands a traced-index scatter into a loop of its own)
    sched = jax.vmap(jnp.interp, in_axes=(None, 0, 0))(t_s, faults.schedule_t, faults.schedule_e)
    effectiveness = jnp.where(faults.has_schedule, sched, faults.value)
    lanes = jnp.arange(out.shape[-1])

    def one_fault(carry, f):
        out, limit = carry
        k, i, v, has_value, onset, acting, eff, on_j, held_j, holding_j = f
        mask = lanes == i
        x = out[i]
        latched = jnp.where(holding_j, held_j, jnp.where(has_value, v, x))
        new = _effect(k, x, v, t_s, onset, eff, latched, on_j)
        out = jnp.where(mask & acting, new, out)
        limit = jnp.where(mask & acting & (k == _SAT), jnp.minimum(limit, v * full), limit)
        stuck_now = acting & (k == _STUCK)
        return (out, limit), (jnp.where(stuck_now, latched, held_j), stuck_now)

    per_fault = (
        faults.kind,
        faults.index,
        faults.value,
        faults.has_value,
        faults.onset,
        active(faults, t_s),
        effectiveness,
        on,
        state.held,
        state.holding,
    )
    (out, limit), (held, holding) = jax.lax.scan(one_fault, (out, limit), per_fault)
    out = jnp.clip(out, -limit, limit)
    return out, FaultState(held=held, holding=holding, on=on, next_switch=next_switch)


def _advance_intermittent(faults: FaultParams, state: FaultState, key: jax.Array, t_s):
    """Toggle each intermittent fault past every switch time up to ``t_s``, drawing the
    next dwell from ``key`` (on: Exp(mean_on), off: Exp(mean_off))."""
    inter = faults.kind == _INTER

    def cond(carry):
        on, nxt, _, _ = carry
        return jnp.any(inter & (t_s >= nxt))

    def body(carry):
        on, nxt, k, count = carry
        k, sub = jax.random.split(k)
        due = inter & (t_s >= nxt)
        on = jnp.where(due, ~on, on)
        dwell = jax.random.exponential(sub, nxt.shape, dtype=nxt.dtype) * jnp.where(on, faults.mean_on, faults.mean_off)
        return on, jnp.where(due, nxt + dwell, nxt), k, count + 1

    if faults.kind.shape[-1] == 0:
        return state.on, state.next_switch
    on, nxt, _, _ = jax.lax.while_loop(cond, body, (state.on, state.next_switch, key, 0))
    return on, nxt


def from_numba_layer(
    realized: list[RealizedFault], n_faults: int, key: jax.Array | None = None, dtype=None
) -> tuple[FaultParams, FaultState]:
    """The arrays and the runtime state of a numba fault layer's ``realized`` faults, at any
    step of its episode (latched stuck values, intermittent phases), padded to ``n_faults``
    entries. An intermittent fault that has not acted yet (the numba layer draws its first
    switch at its first step) gets its first switch drawn with ``key`` (default
    ``PRNGKey(0)``) from the same law. ``dtype``: of the float arrays (default JAX's float)."""
    faults = from_realized(realized, max(int(n_faults), len(realized)))
    fresh = _initial_state_jit(jax.random.PRNGKey(0) if key is None else key, faults)
    held = np.zeros(faults.n_faults)
    holding = np.zeros(faults.n_faults, bool)
    on = np.zeros(faults.n_faults, bool)
    next_switch = np.array(fresh.next_switch, dtype=float)
    for j, f in enumerate(realized):
        if f.held is not None:
            held[j], holding[j] = f.held, True
        if f.next_switch_s is not None:
            on[j], next_switch[j] = f.on, f.next_switch_s
    state = FaultState(
        held=jnp.asarray(held, dtype=dtype),
        holding=jnp.asarray(holding),
        on=jnp.asarray(on),
        next_switch=jnp.asarray(next_switch, dtype=dtype),
    )
    return faults, state


_initial_state_jit = jax.jit(initial_state)


def for_episode(key: jax.Array, configs: list[dict], n_actuators: int, like: FaultParams) -> FaultParams:
    """One episode's faults drawn from ``configs`` with ``key`` (:func:`realize`), padded
    (kind 0) to the entries of ``like`` (the params' faults) and in its dtypes, so that drawn
    and given faults stack (``step``'s autoreset selects between them)."""
    drawn = realize(key, list(configs), n_actuators)
    extra = like.n_faults - drawn.n_faults
    if extra < 0:
        raise ValueError(
            f"params.faults has {like.n_faults} entries, fewer than the {drawn.n_faults} the fault configs draw"
        )
    if extra:
        drawn = jax.tree.map(lambda a, b: jnp.concatenate([a, b.astype(a.dtype)]), drawn, no_faults(extra))
    return jax.tree.map(lambda new, old: new.astype(old.dtype), drawn, like)
