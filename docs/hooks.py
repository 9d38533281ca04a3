"""MkDocs hooks of the documentation site (``hooks:`` in ``mkdocs.yml``).

* The environment pages (``envs/<slug>.md``) are generated from the env classes'
  docstrings, the single source: each docstring's ``**Section.**`` paragraphs become the
  page's sections, its reStructuredText tables and roles become Markdown, and the presets
  section gets a table of every registered preset with each value's source
  (:mod:`attitude_envs.presets`).
* Paper pages carry ``<!-- reproduction-table: ID -->`` markers that are replaced by the
  paper-vs-ours table of the committed reproduction output ``docs/reproductions/ID/ID.md``.
* :class:`ReSTRoles` is a griffe extension (``mkdocstrings`` option ``extensions``) that
  turns the same reStructuredText roles and tables into Markdown in the API reference.

The generator functions (:func:`env_page`, :func:`env_pages`) need no MkDocs; the tests
use them to execute the generated pages' code blocks.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

DOCS = Path(__file__).resolve().parent

#: env id -> (page slug, one-line figure captions keyed by image file under docs/img/envs/)
ENVS: dict[str, tuple[str, dict[str, str]]] = {
    "attitude_envs/ReactionWheel-v0": (
        "reaction-wheel",
        {
            "reaction-wheel-frame.png": 'A frame of `render_mode="rgb_array"`: body axes (solid) and target '
            "axes (dashed), wheel speeds as a fraction of their limit, 20 s into an LQR maneuver.",
            "reaction-wheel.png": "The exact-ZOH LQR (`baselines.lqr.LQRPolicy`) on the default preset, "
            "random target within 60°, seed 0.",
        },
    ),
    "attitude_envs/AirBearing-v0": (
        "air-bearing",
        {
            "air-bearing.png": "The paper's fixed-gain PD (`baselines.pid.PIDPolicy`, Table 3) from the lab "
            "maneuver [10, −10, 10]°, [1, 1, 0] °/s.",
        },
    ),
    "attitude_envs/LinearSystem-v0": (
        "linear-system",
        {
            "linear-system.png": "The discrete LQR on the DARE gain (`baselines.linear_lqr.LinearLQRPolicy`) "
            "from the paper's initial state, 400 s.",
        },
    ),
    "attitude_envs/FuelSlosh-v0": (
        "fuel-slosh",
        {
            "fuel-slosh.png": "The LQR with feasible weights (`baselines.slosh.SloshLQRPolicy`) from the "
            "paper's start state, 1500 s.",
        },
    ),
    "attitude_envs/ConstrainedSlew-v0": ("constrained-slew", {}),
    "attitude_envs/Magnetorquer-v0": (
        "magnetorquer",
        {
            "magnetorquer.png": "AMNFTSMC (`baselines.sliding_mode.AMNFTSMCPolicy`) tracking the default slew "
            "with the paper's magnetorquer faults from 50 s (`sadigh-2022-faults`) in the reproduction's derived "
            "`consistent` configuration (disturbance scaled to what the faulty actuators can reject), first 2500 s.",
        },
    ),
}

#: The modules the API reference documents: roles naming them become links.
API_PAGES = {
    "attitude_envs.envs.base": "api/envs-base.md",
    "attitude_envs.evaluation": "api/evaluation.md",
    "attitude_envs.faults": "api/faults.md",
    "attitude_envs.sensors": "api/sensors.md",
    "attitude_envs.presets": "api/presets.md",
    "attitude_envs.info": "api/info.md",
}

#: The sections every env page has, in this order (docstring headings map onto them).
SECTIONS = (
    "Description",
    "Action space",
    "Observation space",
    "Reward",
    "Starting state",
    "Episode end",
    "Arguments",
    "Presets",
    "Faults and sensors",
    "Info",
    "Version history",
)

# ---------------------------------------------------------------------------------------
# reStructuredText (as the docstrings use it) -> Markdown

_ROLE = re.compile(r":(?:py:)?(mod|class|func|meth|attr|data|obj|exc):`(~?)([^`<]+?)`")
_LITERAL = re.compile(r"``(.+?)``")
_BORDER = re.compile(r"^\s*=+(?: +=+)+\s*$")


def _role(match: re.Match, link_modules: bool, page: str | None) -> str:
    kind, tilde, target = match.groups()
    target = target.strip()
    shown = target.rsplit(".", 1)[-1] if tilde else target
    if kind == "meth" or kind == "func":
        shown += "()"
    if link_modules and kind == "mod" and target in API_PAGES:
        href = API_PAGES[target]
        if page is not None:
            depth = page.count("/")
            href = "../" * depth + href
        return f"[`{shown}`]({href})"
    return f"`{shown}`"


def inline(text: str, link_modules: bool = False, page: str | None = None) -> str:
    """Roles (``:mod:`x```) and double-backtick literals to Markdown code spans."""
    text = _ROLE.sub(lambda m: _role(m, link_modules, page), text)
    return _LITERAL.sub(lambda m: f"`{m.group(1)}`", text)


def _columns(border: str) -> list[tuple[int, int]]:
    return [(m.start(), m.end()) for m in re.finditer(r"=+", border)]


def _cells(line: str, cols: list[tuple[int, int]]) -> list[str]:
    """The cells of one table line; text that runs past a column's right edge (no gap at
    the next column's start) stays in its column."""
    starts = [start for start, _ in cols]
    for i in range(1, len(starts)):
        b = starts[i]
        if 0 < b < len(line) and line[b - 1] != " " and line[b] != " ":
            gap = line.find("  ", b)
            starts[i] = len(line) if gap < 0 else gap
        starts[i] = max(starts[i], starts[i - 1])
    return [line[a:b].strip() for a, b in zip(starts, [*starts[1:], None], strict=True)]


def _join(a: str, b: str) -> str:
    if not a:
        return b
    if not b:
        return a
    if a.endswith("-") or b.startswith("-"):
        return a + b
    return f"{a} {b}"


def _table(lines: list[str], link_modules: bool, page: str | None) -> list[str]:
    """A simple reST table (``===`` borders; a row whose first cell is blank continues the
    row above) as a Markdown table."""
    cols = _columns(lines[0])
    borders = [i for i, line in enumerate(lines) if _BORDER.match(line)]
    header_end = borders[1] if len(borders) >= 3 else None
    rows: list[list[str]] = []
    header: list[str] | None = None
    for i, line in enumerate(lines):
        if _BORDER.match(line):
            if i == header_end and rows:
                header, rows = rows[0], []
            continue
        if not line.strip():
            continue
        cells = _cells(line, cols)
        if rows and not cells[0]:
            rows[-1] = [_join(a, b) for a, b in zip(rows[-1], cells, strict=True)]
        else:
            rows.append(cells)
    if header is None:
        header, rows = [""] * len(cols), rows
    fmt = [inline(c, link_modules, page).replace("|", "\\|") for c in header]
    out = ["| " + " | ".join(fmt) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(inline(c, link_modules, page).replace("|", "\\|") for c in r) + " |")
    return out


def rst_to_md(text: str, link_modules: bool = False, page: str | None = None) -> str:
    """Docstring text (reST roles, literals, simple tables) as Markdown."""
    lines = text.splitlines()
    out: list[str] = []
    prose: list[str] = []

    def flush() -> None:
        # roles and literals may span a line break: convert the prose chunk as a whole
        if prose:
            chunk = re.sub(r"(?<=\S)::$", ":", "\n".join(prose), flags=re.M)  # reST "text::" before a literal block
            chunk = _ROLE.sub(lambda m: _role(m, link_modules, page), re.sub(r"(:`[^`]*?)\n\s*", r"\1 ", chunk))
            chunk = re.sub(r"``(.+?)``", lambda m: "`" + re.sub(r"\s*\n\s*", " ", m.group(1)) + "`", chunk, flags=re.S)
            out.extend(chunk.split("\n"))
            prose.clear()

    i = 0
    while i < len(lines):
        line = lines[i]
        if _BORDER.match(line):
            flush()
            j = i
            block = []
            while j < len(lines) and lines[j].strip():
                block.append(lines[j])
                j += 1
            indent = len(line) - len(line.lstrip())
            block = [b[indent:] for b in block]
            if out and out[-1].strip():
                out.append("")
            out.extend(_table(block, link_modules, page))
            out.append("")
            i = j
            continue
        prose.append(line)
        i += 1
    flush()
    return "\n".join(out)


# ---------------------------------------------------------------------------------------
# docstring sections

_HEADING = re.compile(r"^\*\*([^*]+?)\*\*\s*(.*)$", re.S)
_ALIASES = {
    "description": "Description",
    "action space": "Action space",
    "observation space": "Observation space",
    "reward": "Reward",
    "reward and cost": "Reward",
    "starting state": "Starting state",
    "episode end": "Episode end",
    "arguments": "Arguments",
    "presets": "Presets",
    "faults and sensors": "Faults and sensors",
    "info": "Info",
    "version history": "Version history",
}


def _paragraphs(doc: str) -> list[str]:
    """Blank-line separated blocks (tables stay whole: they have no blank lines)."""
    return [p for p in re.split(r"\n\s*\n", doc.strip()) if p.strip()]


def docstring_sections(cls: type) -> tuple[str, dict[str, str]]:
    """``(summary, {section: text})`` of an env class docstring: a paragraph that starts
    with ``**Name.**`` opens section Name; the paragraphs before the first one are the summary."""
    doc = inspect.getdoc(cls) or ""
    summary: list[str] = []
    sections: dict[str, list[str]] = {}
    current: str | None = None
    for para in _paragraphs(doc):
        m = _HEADING.match(para)
        if m:
            title = m.group(1).strip().rstrip(".").strip()
            name = _ALIASES.get(title.lower(), title)
            rest = m.group(2).strip()
            if rest.startswith("(") and ")" in rest.split("\n", 1)[0]:
                # "**Arguments** (None takes ...):" -> keep the remark as the first paragraph
                rest = rest[1:].replace(")", "", 1).rstrip(":").rstrip() + ("." if rest.rstrip().endswith(":") else "")
            current = name
            sections.setdefault(name, [])
            if rest:
                sections[name].append(rest)
        elif current is None:
            summary.append(para)
        else:
            sections[current].append(para)
    return "\n\n".join(summary), {k: "\n\n".join(v) for k, v in sections.items()}


# ---------------------------------------------------------------------------------------
# values of the presets registry


def _num(x: Any) -> str:
    if isinstance(x, bool | np.bool_):
        return str(bool(x))
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        return f"{float(x):.6g}"
    return str(x)


def format_value(value: Any) -> str:
    """A preset value, short and readable (arrays rounded, diagonal matrices as diag(...))."""
    if isinstance(value, np.ndarray):
        if (
            value.ndim == 2
            and value.shape[0] == value.shape[1]
            and np.count_nonzero(value - np.diag(np.diag(value))) == 0
        ):
            d = np.diag(value)
            if np.all(d == d[0]):
                return f"{_num(d[0])}·I{value.shape[0]}"
            return "diag(" + ", ".join(_num(v) for v in d) + ")"
        if value.ndim == 0:
            return _num(value.item())
        return format_value(value.tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = ", ".join(
            f"{f.name}={format_value(getattr(value, f.name))}" for f in dataclasses.fields(value) if f.init
        )
        return f"{type(value).__name__}({fields})"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {format_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"'
    if value is None:
        return "None"
    return _num(value)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def presets_markdown(env_id: str) -> str:
    """Every registered preset of ``env_id``: name, aliases, description, citation, and a
    table of its values with each value's source (after the first preset, only the values
    that differ from it)."""
    from attitude_envs import presets

    out = []
    first = None
    for p in presets.for_env(env_id):
        aliases = ", ".join(f'`"{a}"`' for a in p.aliases)
        out += [f"### `{p.name}`" + (" (default)" if p.default else ""), ""]
        out += [p.description[:1].upper() + p.description[1:] + ".", ""]
        out += [f"*Paper:* {p.citation}." + (f" *Aliases:* {aliases}." if aliases else ""), ""]
        rows = {k: (format_value(v.value), v.source) for k, v in p.values.items()}
        if first is None:
            first, shown = (p.name, rows), rows
        else:
            shown = {k: v for k, v in rows.items() if first[1].get(k) != v}
            same = sorted(set(rows) - set(shown))
            if same:
                out += [f"The same values as `{first[0]}` but:" if shown else f"The same values as `{first[0]}`.", ""]
        if shown:
            out += ["| keyword | value | source |", "|---|---|---|"]
            out += [f"| `{k}` | `{_cell(v)}` | {_cell(src)} |" for k, (v, src) in shown.items()]
            out.append("")
    return "\n".join(out)


_PRESET_MARKER = re.compile(r"<!--\s*preset-table:\s*(\S+)\s+(\S+)\s*-->")


def preset_table(env: str, name: str) -> str:
    """Every value of one preset with its source, as a Markdown table."""
    from attitude_envs import presets

    p = presets.get(env, name)
    rows = ["| keyword | value | source |", "|---|---|---|"]
    rows += [f"| `{k}` | `{_cell(format_value(v.value))}` | {_cell(v.source)} |" for k, v in p.values.items()]
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------
# env pages


def env_class(env_id: str) -> type:
    import gymnasium as gym

    import attitude_envs  # noqa: F401  (registers the ids)

    entry = gym.spec(env_id).entry_point
    module, name = entry.split(":")
    return getattr(importlib.import_module(module), name)


def _space(space) -> str:
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        low, high = np.unique(space.low), np.unique(space.high)
        if low.size == 1 and high.size == 1:
            return f"Box({_num(low[0])}, {_num(high[0])}, {space.shape}, {space.dtype})"
        return f"Box(shape={space.shape}, dtype={space.dtype})"
    return repr(space)


def env_page(env_id: str) -> str:
    """The Markdown page of ``env_id``, generated from its class docstring and the presets."""
    import gymnasium as gym

    slug, figures = ENVS[env_id]
    page = f"envs/{slug}.md"
    cls = env_class(env_id)
    name = env_id.split("/", 1)[1]
    summary, sections = docstring_sections(cls)
    missing = [s for s in SECTIONS if s not in sections and s != "Presets"]
    if missing:
        raise ValueError(f"{cls.__qualname__}'s docstring has no {missing} section(s) (see docs/hooks.py SECTIONS)")
    spec = gym.spec(env_id)
    env = gym.make(env_id)
    try:
        action, observation = _space(env.action_space), _space(env.observation_space)
    finally:
        env.close()
    from attitude_envs import presets

    names = [p.name for p in presets.for_env(env_id)]
    render = cls.metadata.get("render_modes") or ["none"]
    md = rst_to_md

    out = [
        f"# {name}",
        "",
        "<!-- Generated by docs/hooks.py from the env class docstring; edit the docstring, not this page. -->",
        "",
        md(summary, True, page),
        "",
        f"| id | `{env_id}` |",
        "|---|---|",
        f"| class | `{cls.__module__}.{cls.__qualname__}` |",
        f"| action space (default preset) | `{action}` |",
        f"| observation space (default preset) | `{observation}` |",
        f"| presets | {', '.join(f'`{n}`' for n in names)} |",
        f"| batched env | `{spec.vector_entry_point}` |" if spec.vector_entry_point else "| batched env | — |",
        f"| render modes | {', '.join(f'`{m}`' for m in render)} |",
        "",
    ]
    for image, caption in figures.items():
        alt = caption.replace("`", "").replace('"', "")
        out += [f"![{name}: {alt}](../img/envs/{image})", "", f"*{caption}*", ""]
    out += [
        "```python",
        "import gymnasium as gym",
        "",
        "import attitude_envs  # noqa: F401  (registers the ten ids: -v0 and -v1 of five plants)",
        "",
        f'env = gym.make("{env_id}")',
        "obs, info = env.reset(seed=0)",
        "obs, reward, terminated, truncated, info = env.step(env.action_space.sample())",
        'print(obs.shape, reward, info["cost"], sorted(info["truth"]))',
        "```",
        "",
    ]
    for section in SECTIONS:
        text = sections.get(section, "")
        out += [f"## {section}", ""]
        if text:
            out += [md(text, True, page), ""]
        if section == "Presets":
            out += [presets_markdown(env_id), ""]
    for extra, text in sections.items():
        if extra not in SECTIONS:
            out += [f"## {extra}", "", md(text, True, page), ""]
    return "\n".join(out).rstrip() + "\n"


def env_pages() -> dict[str, str]:
    """``{docs path: Markdown}`` of the five env pages."""
    return {f"envs/{slug}.md": env_page(env_id) for env_id, (slug, _) in ENVS.items()}


# ---------------------------------------------------------------------------------------
# reproduction tables

_MARKER = re.compile(r"<!--\s*reproduction-table:\s*([a-z0-9-]+)((?:\s+[a-z-]+(?:=[^\s]+)?)*)\s*-->")
_COLUMNS = ("case", "controller", "metric")


def reproduction_table(rid: str, filters: str = "") -> str:
    """The paper-vs-ours table of the committed output ``docs/reproductions/<rid>/<rid>.md``.

    ``filters``: ``paper-only`` keeps the rows with a paper value; ``case=a,b``,
    ``controller=...``, ``metric=...`` keep the rows whose column is one of the values
    (``+`` stands for a space)."""
    text = (DOCS / "reproductions" / rid / f"{rid}.md").read_text(encoding="utf-8")
    lines = [line for line in text.split("## Notes", 1)[0].splitlines() if line.startswith("|")]
    if len(lines) < 3:
        raise ValueError(f"docs/reproductions/{rid}/{rid}.md has no table")
    header, rule, rows = lines[0], lines[1], lines[2:]
    for token in filters.split():
        if token == "paper-only":
            rows = [r for r in rows if r.split("|")[4].strip() != "—"]
            continue
        key, _, values = token.partition("=")
        if key not in _COLUMNS:
            raise ValueError(f"reproduction-table filter {token!r}: use paper-only or {_COLUMNS}=v1,v2")
        wanted = {v.replace("+", " ") for v in values.split(",")}
        col = _COLUMNS.index(key) + 1
        rows = [r for r in rows if r.split("|")[col].strip() in wanted]
    if not rows:
        raise ValueError(f"reproduction-table {rid} {filters!r} selects no row")
    return "\n".join([header, rule, *rows])


# ---------------------------------------------------------------------------------------
# speed table

_SPEED_MARKER = "<!-- speed-table -->"


def speed_table() -> str:
    """The speed benchmark's rows (``benchmarks/results.json``, written by ``python -m benchmarks``)."""
    import json

    data = json.loads((DOCS.parent / "benchmarks" / "results.json").read_text(encoding="utf-8"))
    out = ["| benchmark | env | N | result |", "|---|---|---|---|"]
    for r in data["rows"]:
        env = r["env"].replace("attitude_envs/", "")
        n = str(r.get("num_envs", ""))
        if "us_per_step" in r:
            result = f"{r['us_per_step']:.1f} µs/step, {r['ratio_to_reference']:.2f}× Pendulum-v1"
        elif "native_speedup" in r:
            result = f"{r['steps_per_s'] / 1e3:.1f} k steps/s; native is **{r['native_speedup']:.0f}×** faster"
        elif "ratio_to_cartpole_4096" in r:
            result = f"{r['steps_per_s'] / 1e6:.2f} M steps/s"
            if r.get("num_envs") == 4096:
                result += f" ({r['ratio_to_cartpole_4096']:.2f}× CartPole)"
        elif "steps_per_s" in r:
            result = (
                f"{r['steps_per_s'] / 1e6:.2f} M steps/s"
                if r["steps_per_s"] > 1e6
                else f"{r['steps_per_s'] / 1e3:.1f} k steps/s"
            )
        elif "episodes_per_s" in r:
            result = f"{r['episodes_per_s']:.0f} episodes/s"
        elif "samples_to_1e-6" in r:
            result = f"{r['samples_to_1e-6']} samples to 1e-6 gain error, {r['wall_s']:.3f} s"
        else:
            result = ", ".join(f"{k} {v}" for k, v in r.items() if k not in ("benchmark", "env"))
        out.append(f"| {r['benchmark']} | {env} | {n} | {result} |")
    meta = data.get("meta", {})
    out += [
        "",
        f"*Machine:* {meta.get('machine', '?')}, Python {meta.get('python', '?')}; "
        f"the whole benchmark took {meta.get('wall_s', 0):.0f} s.",
    ]
    return "\n".join(out)


# ---------------------------------------------------------------------------------------
# MkDocs events


def on_files(files, config):
    from mkdocs.structure.files import File

    for path, text in env_pages().items():
        files.append(File.generated(config, path, content=text))
    return files


_SOURCE_LINE = re.compile(r"^Source: (.+)$", re.M)
_PAPER_PAGES = {
    "feedback-linearization": "feedback-linearization.md",
    "q-learning-lqr": "heravi-2017.md",
    "fault-tolerant-smc": "sadigh-2022.md",
    "ga-pid": "air-bearing-pid.md",
    "fuel-slosh": "fuel-slosh.md",
}


def on_page_markdown(markdown, page, config, files):
    markdown = _MARKER.sub(lambda m: reproduction_table(m.group(1), m.group(2)), markdown)
    markdown = _PRESET_MARKER.sub(lambda m: preset_table(m.group(1), m.group(2)), markdown)
    if _SPEED_MARKER in markdown:
        markdown = markdown.replace(_SPEED_MARKER, speed_table())
    src = page.file.src_uri
    if src.startswith("reproductions/"):
        rid = src.split("/")[1]
        if rid in _PAPER_PAGES:
            markdown = _SOURCE_LINE.sub(
                lambda m: (
                    f"Source: {m.group(1)}. The paper's [page](../../papers/{_PAPER_PAGES[rid]}) has the full "
                    "citation, the reconstruction decisions and which claims hold; this page is the raw output of "
                    f"`attitude-envs reproduce {rid}`."
                ),
                markdown,
                count=1,
            )
    return markdown


# ---------------------------------------------------------------------------------------
# griffe extension for the API reference

try:
    import griffe

    class ReSTRoles(griffe.Extension):
        """Docstrings' reST roles, literals and simple tables as Markdown (mkdocstrings)."""

        def on_instance(self, *, node, obj, agent, **kwargs) -> None:
            if obj.docstring is not None:
                obj.docstring.value = rst_to_md(obj.docstring.value)

except ImportError:  # griffe comes with the docs extra; the generators above do not need it
    pass
