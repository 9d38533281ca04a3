"""The campaign YAML schema: :class:`Campaign` and its envs and agents, checked completely at load.

:func:`load_campaign` refuses a bad campaign before anything runs, with a one-line
``ValueError`` naming the key (``agents[2].train.timesteps``) and what it accepts. Seeds take
the one seeds syntax of :mod:`experiments.seeds`.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import load_env_creator

import attitude_envs  # noqa: F401  (registers the env ids)
from attitude_envs import validation
from attitude_envs.evaluation.success import SuccessMetric
from attitude_envs.make import check_env_id
from experiments.optimum_table import solve_by_default
from experiments.policies import check_policy_env, check_policy_name
from experiments.seeds import parse_seeds
from experiments.training.algorithm import Algorithm
from experiments.training.hyperparams import load_hyperparams, read_yaml

PLANT_CAMPAIGNS = ("wheel", "air-bearing", "magnetorquer", "slosh", "linear")  # one per plant, in this order
TASK_CAMPAIGNS = ("slew",)  # tasks on a plant beyond its paper's: the constrained slews of ConstrainedSlew-v0
ALL_CAMPAIGNS = (*PLANT_CAMPAIGNS, *TASK_CAMPAIGNS)  # `--config all`, in this order
PRESETS = ("quick", "full", *ALL_CAMPAIGNS)
SELECT = ("best", "final")  # which snapshot of a trained agent is evaluated

TOP_KEYS = ("name", "description", "seeds", "envs", "agents", "metrics", "success_error_deg")
TOP_KEYS += ("success_state_fraction", "video", "optimum", "layers")
ENV_KEYS = ("name", "id", "kwargs", "scenarios", "faults")
AGENT_KEYS = ("name", "policy", "params", "model", "learn", "envs", "optional", "train", "note", "env_id", "env_kwargs")
AGENT_KEYS += ("models_of",)
TRAIN_KEYS = ("algo", "backend", "timesteps", "seeds", "select", "env_kwargs", "overrides", "hyperparams_file")
TRAIN_KEYS += ("checkpoint_freq", "eval_freq", "eval_episodes", "env")

#: the campaign key that sets each success metric's threshold (:mod:`attitude_envs.evaluation.success`)
SUCCESS_KEYS = {"final_error_deg": "success_error_deg", "final_state_fraction": "success_state_fraction"}

#: the accepted interval of each ``metrics`` option (the keyword arguments of
#: :func:`attitude_envs.evaluation.metrics.episode_metrics`): (low, high, open low, open high)
METRIC_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "settling_band": (0.0, 1.0, True, True),
    "settling_band_deg": (0.0, math.inf, True, True),
    "steady_state_fraction": (0.0, 1.0, True, False),
    "wheel_speed_limit_rad_s": (0.0, math.inf, True, True),
}


@dataclass(frozen=True)
class EnvSpec:
    name: str
    id: str
    kwargs: dict[str, Any]
    scenarios: list[dict[str, Any]]
    faults: dict[str, list[dict[str, Any]]]


@dataclass(frozen=True)
class AgentSpec:
    """One agent: ``spec`` is what :func:`~experiments.policies.build_policy` gets; ``train``
    (SB3 agents trained by the campaign) has its ``seeds`` parsed to a list; ``note`` is shown
    beside the agent in the report's leaderboards.

    ``env_id`` and ``env_kwargs`` pose the agent's own task on the cells' episodes (see
    :func:`play_env`): another version of the cell's env (``AirBearing-v1``'s learning task on
    an ``AirBearing-v0`` cell) and task keywords (``control_dt_s``, ``termination_cost``, …:
    ``task_keywords`` of the env class). The episodes, the running cost and J* stay the
    cell's, so J / J* compares agents that decide at different periods on the same yardstick
    (J* is solved at the cell's period).

    ``models_of`` (SB3 agents): the name of an earlier agent whose trained models this one plays,
    one per training seed, with its own ``params`` (``shield: cbf`` puts them behind the CBF
    safety filter at deployment, ``estimator: mekf`` acts on the estimator's observation): a
    second row of the same training, no training of its own, on the source's envs or some of them.

    ``train.env`` (an env entry's name): the agent trains on that entry only and plays those
    models on every entry it plays (trained in the lab, scored under flight conditions too);
    absent, it trains on each entry it plays, one training per entry."""

    name: str
    spec: dict[str, Any]
    envs: list[str] | None
    optional: bool
    train: dict[str, Any] | None
    note: str | None = None
    env_id: str | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    models_of: str | None = None


def task_keywords(env_id: str) -> frozenset[str]:
    """The task keywords of the env class of ``env_id`` (empty for an env without them)."""
    entry = gym.spec(env_id).entry_point
    creator = load_env_creator(entry) if isinstance(entry, str) else entry
    return frozenset(getattr(creator, "task_keywords", ()))


def play_env(agent: AgentSpec, env_id: str, kwargs: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """The env id and keyword arguments ``agent`` plays a cell of ``env_id`` built with
    ``kwargs`` on: the cell's own without an agent ``env_id``/``env_kwargs``; with an
    ``env_id``, the cell's kwargs less its task keywords (the agent's env sets its own), then
    the agent's ``env_kwargs`` over them."""
    if agent.env_id is None and not agent.env_kwargs:
        return env_id, kwargs
    task = task_keywords(env_id)
    base = {k: v for k, v in kwargs.items() if agent.env_id is None or k not in task}
    return agent.env_id or env_id, {**base, **copy.deepcopy(agent.env_kwargs)}


@dataclass
class Campaign:
    name: str
    seeds: list[int]
    envs: list[EnvSpec]
    agents: list[AgentSpec]
    metrics: dict[str, Any] = field(default_factory=dict)
    success_error_deg: float = 2.0
    success_state_fraction: float = 0.1
    video: bool = False
    source: str = ""
    fingerprint: str = ""
    #: the identities of its parts (:func:`_parts`): what a run folder's results may be resumed under
    parts: dict[str, Any] = field(default_factory=dict)
    optimum_solve: bool = True  # solve J* on demand for episodes outside the shipped table (casadi)
    optimum_table: str | None = None  # a J* table in place of the shipped one (tests, private cells)
    #: the report's "what each layer costs" pairs: ``{"name", "without", "with"}`` (agent names)
    layers: list[dict[str, str]] = field(default_factory=list)

    def agents_for(self, env: EnvSpec) -> list[AgentSpec]:
        return [a for a in self.agents if a.envs is None or env.name in a.envs]

    def trained_by(self, agent: AgentSpec) -> AgentSpec | None:
        """The agent whose training ``agent`` plays: itself when it trains, the agent it names
        in ``models_of``, else None."""
        if agent.models_of is not None:
            return next(a for a in self.agents if a.name == agent.models_of)
        return agent if agent.train is not None else None

    def trained_on(self, agent: AgentSpec, env: EnvSpec) -> str:
        """The name of the env entry whose training ``agent`` plays on ``env``: ``train.env``
        of the agent it plays the models of, else ``env``'s own."""
        source = self.trained_by(agent)
        return (source.train or {}).get("env", env.name) if source is not None else env.name

    def success_threshold(self, metric: SuccessMetric) -> float:
        """The threshold this campaign sets for ``metric`` (:data:`SUCCESS_KEYS`), else the metric's default."""
        key = SUCCESS_KEYS.get(metric.name)
        return float(getattr(self, key)) if key is not None else metric.threshold

    @property
    def agent_notes(self) -> dict[str, str]:
        """Agent name → its ``note``, for the agents that have one."""
        return {a.name: a.note for a in self.agents if a.note is not None}


def preset_path(name: str) -> Path:
    """The shipped campaign file of preset ``name``."""
    return Path(str(resources.files("experiments") / "campaigns" / f"{name}.yml"))


def _require(cond: bool, message: str) -> None:
    if not cond:
        raise ValueError(message)


def _name(where: str, value: Any) -> str:
    _require(
        isinstance(value, str) and value and all(c.isalnum() or c in "-_.+" for c in value),
        f"{where} must be a non-empty name of letters, digits, '-', '_', '.' or '+' (a controller and its "
        f"estimator: lqr+mekf), got {value!r}",
    )
    return value


def _number(
    where: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    open_low: bool = False,
    open_high: bool = False,
    integer: bool = False,
    absent: str = "",
) -> Any:
    """``value`` when it is a finite number in the interval (a whole one with ``integer``), else
    a ``ValueError`` naming ``where`` and the interval (``absent``: what leaving it out means)."""
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (not integer or float(value).is_integer())
    ok = ok and (value > low if open_low else value >= low) and (value < high if open_high else value <= high)
    kind = "an integer" if integer else "a number"
    _require(
        ok, f"{where} must be {kind} in {validation.interval(low, high, open_low, open_high)}{absent}, got {value!r}"
    )
    return value


def _mapping(where: str, value: Any) -> dict[str, Any]:
    """``value`` (None: empty) as a dict, else a ``ValueError`` naming ``where``."""
    _require(value is None or isinstance(value, dict), f"{where} must be a mapping, got {value!r}")
    return dict(value or {})


def _known(where: str, data: dict[str, Any], accepted: tuple[str, ...]) -> None:
    unknown = set(data) - set(accepted)
    _require(not unknown, f"{where} has unknown keys {sorted(unknown)}; accepted: {list(accepted)}")


def _metrics(value: Any) -> dict[str, Any]:
    metrics = _mapping("metrics", value)
    _known("metrics", metrics, tuple(METRIC_RANGES))
    for key, value in metrics.items():
        if key == "wheel_speed_limit_rad_s" and value is None:
            continue  # not checked
        low, high, open_low, open_high = METRIC_RANGES[key]
        _number(f"metrics.{key}", value, low, high, open_low=open_low, open_high=open_high)
    return metrics


def _env(i: int, e: Any) -> EnvSpec:
    _require(isinstance(e, dict) and "id" in e, f"envs[{i}] must be a mapping with an 'id', got {e!r}")
    _known(f"envs[{i}]", e, ENV_KEYS)
    check_env_id(str(e["id"]))
    name = _name(f"envs[{i}].name", e.get("name", str(e["id"]).split("/")[-1]))
    scenarios = e.get("scenarios") or [{"name": "default"}]
    _require(isinstance(scenarios, list), f"envs[{i}].scenarios must be a list of mappings, got {scenarios!r}")
    for j, s in enumerate(scenarios):
        _require(isinstance(s, dict), f"envs[{i}].scenarios[{j}] must be a mapping, got {s!r}")
        _name(f"envs[{i}].scenarios[{j}].name", s.get("name"))
        bad = set(s) - {"name", "options", "env_kwargs"}
        _require(
            not bad, f"envs[{i}].scenarios[{j}] has unknown keys {sorted(bad)}; accepted: name, options, env_kwargs"
        )
        _mapping(f"envs[{i}].scenarios[{j}].options", s.get("options"))
        _mapping(f"envs[{i}].scenarios[{j}].env_kwargs", s.get("env_kwargs"))
    faults = e.get("faults") or {"none": []}
    _require(isinstance(faults, dict), f"envs[{i}].faults must map names to fault lists, got {faults!r}")
    for fname, flist in faults.items():
        _name(f"envs[{i}].faults key", fname)
        _require(isinstance(flist, list), f"envs[{i}].faults.{fname} must be a list of fault dicts, got {flist!r}")
    return EnvSpec(name, str(e["id"]), _mapping(f"envs[{i}].kwargs", e.get("kwargs")), list(scenarios), dict(faults))


def _train(where: str, train: Any, envs: list[EnvSpec], env_id: str | None = None) -> dict[str, Any]:
    """The checked ``train`` mapping of an agent trained on ``envs`` (on its own ``env_id``
    when it names one: its hyperparameter entry), its ``seeds`` parsed."""
    _require(isinstance(train, dict) and "algo" in train, f"{where} needs an algo, got {train!r}")
    _known(where, train, TRAIN_KEYS)
    algorithm = Algorithm(train["algo"], train.get("backend", "sb3")).trainable()
    train = {**train, "seeds": parse_seeds(train.get("seeds", [0]), f"{where}.seeds")}
    if train.get("timesteps") is not None:
        absent = " (or absent: the hyperparameter entry's n_timesteps)"
        _number(f"{where}.timesteps", train["timesteps"], 1, integer=True, absent=absent)
    for key in ("checkpoint_freq", "eval_freq"):
        if key in train:
            _number(f"{where}.{key}", train[key], 1, integer=True, absent=" (env steps; absent: 10000)")
    if "eval_episodes" in train:  # validation episodes (seeds 10000+) that choose the best snapshot
        _number(f"{where}.eval_episodes", train["eval_episodes"], 1, integer=True, absent=" (absent: 5)")
    select = train.get("select", "best")
    _require(select in SELECT, f"{where}.select must be one of {list(SELECT)}, got {select!r}")
    _mapping(f"{where}.env_kwargs", train.get("env_kwargs"))
    if "env" in train:
        _require(
            train["env"] in {e.name for e in envs},
            f"{where}.env names the env entry the agent trains on, one of those it plays "
            f"{[e.name for e in envs]}, got {train['env']!r}",
        )
        envs = [e for e in envs if e.name == train["env"]]
    overrides = _mapping(f"{where}.overrides", train.get("overrides"))
    hp_file = train.get("hyperparams_file")
    _require(hp_file is None or isinstance(hp_file, str), f"{where}.hyperparams_file must be a path, got {hp_file!r}")
    for env in envs:
        try:
            load_hyperparams(algorithm, env_id or env.id, hp_file, overrides)
        except ValueError as exc:
            raise ValueError(f"{where} on env {env.name!r}: {exc}") from None
    return train


def _agent(i: int, a: Any, envs: list[EnvSpec]) -> AgentSpec:
    _require(isinstance(a, dict) and "policy" in a, f"agents[{i}] must be a mapping with a 'policy', got {a!r}")
    name = _name(f"agents[{i}].name", a.get("name", a["policy"]))
    check_policy_name(str(a["policy"]))
    _known(f"agents[{i}]", a, AGENT_KEYS)
    only = a.get("envs")
    if only is not None:
        _require(
            isinstance(only, list) and all(isinstance(e, str) for e in only),
            f"agents[{i}].envs must be a list of env names, got {only!r}",
        )
        unknown_envs = set(only) - {e.name for e in envs}
        _require(
            not unknown_envs,
            f"agents[{i}].envs names unknown envs {sorted(unknown_envs)}; accepted: {[e.name for e in envs]}",
        )
    for env in envs:  # a pairing the policy does not fit fails here, not in a worker hours later
        if only is None or env.name in only:
            try:
                check_policy_env(str(a["policy"]), env.id)
            except ValueError as exc:
                raise ValueError(f"agents[{i}] ({name}) on env {env.name!r}: {exc}") from None
    agent_env_id, agent_env_kwargs = _agent_task(i, name, a, [e for e in envs if only is None or e.name in only])
    train = a.get("train")
    models_of = a.get("models_of")
    if models_of is not None:
        _require(
            a["policy"] == "sb3" and train is None and "model" not in a and isinstance(models_of, str),
            f"agents[{i}] ({name}).models_of names the agent whose trained models it plays (policy sb3, "
            f"no train or model of its own), got {models_of!r}",
        )
    elif train is not None:
        _require(a["policy"] == "sb3", f"agents[{i}] ({name}): train is only for policy sb3")
        train = _train(f"agents[{i}].train", train, [e for e in envs if only is None or e.name in only], agent_env_id)
    elif a["policy"] == "sb3":
        _require(
            "model" in a,
            f"agents[{i}] ({name}): policy sb3 needs model: PATH, train: {{algo: ...}} or models_of: AGENT",
        )
    if "model" in a:
        _require(isinstance(a["model"], str), f"agents[{i}].model must be a path, got {a['model']!r}")
    for key in ("params", "learn"):
        _mapping(f"agents[{i}].{key}", a.get(key))
    optional = a.get("optional", False)
    _require(isinstance(optional, bool), f"agents[{i}].optional must be true or false, got {optional!r}")
    note = a.get("note")
    _require(
        note is None or isinstance(note, str) and note.strip() != "" and "\n" not in note.strip(),
        f"agents[{i}].note must be one line of text (shown beside the agent in the report), got {note!r}",
    )
    spec = {k: v for k, v in a.items() if k not in ("envs", "optional", "train", "note", "env_id", "env_kwargs")}
    spec.pop("models_of", None)
    note = note.strip() if note is not None else None
    return AgentSpec(name, spec, only, optional, train, note, agent_env_id, agent_env_kwargs, models_of)


def _check_models_of(agents: list[AgentSpec]) -> None:
    """Each ``models_of`` names an earlier trained agent that plays the same task, on the same
    envs or some of them (a row behind an estimator plays only the cells with sensors)."""
    for i, a in enumerate(agents):
        if a.models_of is None:
            continue
        source = next((b for b in agents[:i] if b.name == a.models_of), None)
        _require(
            source is not None and source.train is not None,
            f"agents[{i}] ({a.name}).models_of must name an earlier agent with train, got {a.models_of!r}",
        )
        within = source.envs is None or (a.envs is not None and set(a.envs) <= set(source.envs))
        _require(
            within and (source.env_id, source.env_kwargs) == (a.env_id, a.env_kwargs),
            f"agents[{i}] ({a.name}) plays the models of {source.name}: give it the same env_id and env_kwargs, "
            f"and its envs or some of them",
        )


def _agent_task(i: int, name: str, a: dict[str, Any], envs: list[EnvSpec]) -> tuple[str | None, dict[str, Any]]:
    """The checked ``env_id`` and ``env_kwargs`` of agent ``a`` on ``envs`` (see :class:`AgentSpec`)."""
    env_id = a.get("env_id")
    if env_id is not None:
        _require(isinstance(env_id, str), f"agents[{i}].env_id must be an env id, got {env_id!r}")
        try:
            check_env_id(env_id)
        except ValueError as exc:
            raise ValueError(f"agents[{i}].env_id: {exc}") from None
        for env in envs:
            _require(
                gym.spec(env_id).entry_point == gym.spec(env.id).entry_point,
                f"agents[{i}] ({name}).env_id {env_id!r} is not a version of env {env.name!r} ({env.id}): "
                "an agent plays the cell's episodes, on the same plant",
            )
    kwargs = _mapping(f"agents[{i}].env_kwargs", a.get("env_kwargs"))
    for env in envs:
        accepted = task_keywords(env.id)
        bad = sorted(set(kwargs) - accepted)
        _require(
            not bad,
            f"agents[{i}] ({name}).env_kwargs may set only the task keywords of env {env.name!r} "
            f"{sorted(accepted)} (the episodes stay the cell's), got {bad}",
        )
    return env_id, kwargs


def _fingerprint(data: dict[str, Any]) -> str:
    """The campaign's identity (its results never mix with another's); notes and layers are left
    out: they change the report, not the results."""
    data = {k: v for k, v in data.items() if k != "layers"}
    agents = data.get("agents")
    if isinstance(agents, list):
        data = {
            **data,
            "agents": [{k: v for k, v in a.items() if k != "note"} if isinstance(a, dict) else a for a in agents],
        }
    return _digest(data)


def _parts(data: dict[str, Any]) -> dict[str, Any]:
    """The identities of a campaign's parts: ``setup``, everything but its agents, layers,
    description and video (its name, envs, cells, seeds, metrics, success thresholds and J*
    settings), and each agent's by name, its note left out. An agent's episodes depend only on the setup and its own entry, so results
    recorded under other agents stay valid when agents are added or removed (:func:`resumable`)."""
    setup = {k: v for k, v in data.items() if k not in ("agents", "layers", "description", "video")}
    agents = {}
    for a in data.get("agents") or []:
        name = str(a.get("name", a.get("policy")))
        agents[name] = _digest({**{k: v for k, v in a.items() if k != "note"}, "name": name})
    return {"setup": _digest(setup), "agents": agents}


def _digest(data: Any) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16]


def resumable(recorded: dict[str, Any], campaign: Campaign) -> str | None:
    """None when a run folder whose ``campaign.json`` holds ``recorded`` may go on under
    ``campaign``: the same definition, or the same setup with every agent that both name defined
    alike (agents added or removed); else what differs, in words."""
    if recorded.get("fingerprint") == campaign.fingerprint:
        return None
    before = recorded.get("parts")
    if not isinstance(before, dict):  # written before the parts were recorded
        return (
            "its definition changed, and the folder was written before agents could be added or removed: rerun "
            "it once with its own definition, then change its agents"
        )
    if before.get("setup") != campaign.parts["setup"]:
        return "its name, envs, cells, seeds, metrics, success thresholds or J* settings changed"
    changed = sorted(n for n, h in (before.get("agents") or {}).items() if campaign.parts["agents"].get(n, h) != h)
    if changed:
        return (
            f"the definition of agent(s) {', '.join(changed)} changed (as recorded in the folder; agents may only "
            "be added or removed)"
        )
    return None


def load_campaign(config: str | Path | dict, backend: str | None = None) -> Campaign:
    """A campaign from a preset name (:data:`PRESETS`), a YAML path or a dict; ``ValueError``
    naming the offending entry otherwise. ``backend`` (``sb3`` / ``sbx``) replaces every trained
    agent's ``train.backend`` (a different campaign: its own fingerprint)."""
    source = str(config) if not isinstance(config, dict) else "<dict>"
    if isinstance(config, str) and config in PRESETS:
        data = read_yaml(preset_path(config))
    elif isinstance(config, str | Path):
        path = Path(config)
        _require(
            path.suffix in (".yml", ".yaml") or path.is_file(),
            f"--config must be one of {list(PRESETS)} or a YAML file path, got {str(config)!r}"
            " (the command line also takes all: the plant campaigns)",
        )
        data = read_yaml(path)
    else:
        data = copy.deepcopy(config)
    _require(isinstance(data, dict), f"campaign {source!r} must be a mapping, got {type(data).__name__}")
    if backend is not None:
        for agent in data.get("agents") or []:
            if isinstance(agent, dict) and isinstance(agent.get("train"), dict):
                agent["train"]["backend"] = backend
    _known("campaign", data, TOP_KEYS)
    name = _name("name", data.get("name", "campaign"))
    description = data.get("description", "")
    _require(isinstance(description, str), f"description must be text, got {description!r}")
    seeds = parse_seeds(data.get("seeds", 5), "seeds")
    envs_data = data.get("envs") or []
    _require(isinstance(envs_data, list), f"envs must be a list of mappings, got {envs_data!r}")
    envs = [_env(i, e) for i, e in enumerate(envs_data)]
    _require(bool(envs), "campaign needs at least one entry under envs")
    _require(len({e.name for e in envs}) == len(envs), "env names must be distinct")
    agents_data = data.get("agents") or []
    _require(isinstance(agents_data, list), f"agents must be a list of mappings, got {agents_data!r}")
    agents = [_agent(i, a, envs) for i, a in enumerate(agents_data)]
    _require(bool(agents), "campaign needs at least one entry under agents")
    _require(len({a.name for a in agents}) == len(agents), "agent names must be distinct")
    _check_models_of(agents)
    metrics = _metrics(data.get("metrics"))
    error_deg = _number("success_error_deg", data.get("success_error_deg", 2.0), 0.0, 180.0, open_low=True)
    fraction = _number("success_state_fraction", data.get("success_state_fraction", 0.1), 0.0, 1.0, open_low=True)
    video = data.get("video", False)
    _require(isinstance(video, bool), f"video must be true or false, got {video!r}")
    opt = data.get("optimum") or {}
    _require(
        isinstance(opt, dict) and not set(opt) - {"solve", "table"},
        f"optimum must be a mapping with keys solve (true/false), table (a J* table path), got {opt!r}",
    )
    _require(isinstance(opt.get("solve", True), bool), f"optimum.solve must be true or false, got {opt.get('solve')!r}")
    layers = _layers(data.get("layers"), [a.name for a in agents])
    return Campaign(
        name=name,
        seeds=seeds,
        envs=envs,
        agents=agents,
        metrics=metrics,
        success_error_deg=float(error_deg),
        success_state_fraction=float(fraction),
        video=video,
        optimum_solve=bool(opt.get("solve", solve_by_default())),
        optimum_table=str(opt["table"]) if opt.get("table") is not None else None,
        source=source,
        fingerprint=_fingerprint(data),
        parts=_parts(data),
        layers=layers,
    )


def _layers(value: Any, agents: list[str]) -> list[dict[str, str]]:
    """The checked ``layers``: a list of ``{name: text, without: AGENT, with: AGENT}``, each pair
    two of the campaign's agents that differ by one layer (a safety filter, a penalty): the
    report shows what the layer costs in J and what it changes in the violations."""
    value = value or []
    _require(isinstance(value, list), f"layers must be a list of {{name, without, with}}, got {value!r}")
    for i, layer in enumerate(value):
        _require(
            isinstance(layer, dict) and set(layer) == {"name", "without", "with"},
            f"layers[{i}] must be a mapping with exactly name, without, with, got {layer!r}",
        )
        for key in ("without", "with"):
            _require(
                layer[key] in agents,
                f"layers[{i}].{key} must name an agent of the campaign {agents}, got {layer[key]!r}",
            )
    return [dict(layer) for layer in value]
