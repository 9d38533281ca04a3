"""Every command line the documentation shows exists, and a long one says how long it runs.

The commands are taken from ``README.md`` and ``docs/**/*.md`` (not the generated pages:
``docs/reproductions/``, ``docs/full-campaign/``, ``docs/campaigns/*/report.md``): in shell code
blocks (``bash``, ``sh``, ``shell``, ``console``; ``\\`` continuations joined) and in inline
code spans, each command that starts with ``attitude-envs``, ``python train.py``,
``python -m benchmarks…``, ``python -m experiments…`` or ``python benchmarks/….py``
(it ends at ``&&``, ``;`` or the end of the line).

1. ``test_doc_command_parses``: its arguments parse with the real parser,
   ``experiments.cli.build_parser()`` for ``attitude-envs`` and ``python train.py`` (and name
   no option it hides, such as the old ``--workers``), the module's own ``main`` (stopped right
   after its ``parse_args``) for ``python -m`` and ``python benchmarks/….py``.
   Before parsing, comments are dropped, optional parts ``[--opt X]`` opened, alternatives
   ``a|b|c`` give their first, and the placeholders ``ID``, ``N``, ``S``, ``YAML`` get a
   sample value (the other upper-case words, ``DIR``, ``RUN``, …, and ``<id>`` stand as they are).
2. ``test_doc_command_names_real_options``: every ``--option`` a command shows is one of its
   parser's own option strings, spelled out. argparse also takes a unique prefix (``--check`` for
   ``--checkpoint-freq``), so a renamed or shortened option in the docs would still parse in
   test 1 while meaning something else, or nothing, to a reader.
3. ``test_doc_synopsis_lists_every_option``: a *synopsis* (a code-block command with optional
   parts ``[--opt X]``, such as ``train``'s in ``docs/guide/training.md``) shows every option its
   parser has (but ``--help`` and hidden ones). Both directions fail: an option a synopsis names
   that the parser lacks fails test 1 (or 2); an option the parser has and the synopsis leaves out
   fails here, because a synopsis is where a reader looks up what a command takes (the train
   synopsis once left out ``--eval-episodes``, ``--eval-freq`` and ``--checkpoint-freq``).
   An example command (no ``[...]``) shows only the options it uses and is not held to this.
4. ``test_doc_command_says_how_long``: a command that is not known-fast has a time statement
   (``≈ 3 min``, ``about 90 s``, ``1 h 29 min``, ``under a minute``, ``seconds``) in its trailing
   comment or in the comment line just above it (code blocks), or on its own source line(s) or
   the line after, outside code spans (inline).

Known-fast (well under 2 min on 2 cores), the whole rule:

* ``--help``, ``envs``, ``demo`` (5 seeds by default), and ``--quick`` anywhere;
* ``benchmark --config quick`` (its time is stated once, on the getting-started page);
* ``evaluate`` on ReactionWheel-v0 (the default env) with at most 20 seeds (``--seeds``; default
  5) and no ``mpc`` policy (with the ``optimal`` extra installed it also solves J* of each
  episode outside the shipped table: seconds each there, up to minutes on the other envs);
* an inline ``attitude-envs SUBCOMMAND`` (or ``python train.py <cmd>``) with nothing after it
  names a subcommand and is not a command (the subcommand must exist).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import inspect
import re
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from experiments.cli import build_parser
from experiments.seeds import parse_seeds

ROOT = Path(__file__).resolve().parents[1]
GENERATED_DIRS = ("reproductions", "full-campaign")
SHELL_BLOCK = re.compile(r"^```(?:bash|sh|shell|console)[^\n]*\n(.*?)^```", re.S | re.M)
ANY_BLOCK = re.compile(r"^```[^\n]*\n.*?^```", re.S | re.M)
INLINE = re.compile(r"`([^`]+)`")
#: where a command starts: this package's entry points
START = re.compile(
    r"(?:PYTHONPATH=\S+\s+)?(?:attitude-envs(?=\s|$)|python3? train\.py\b|python3? -m (?:benchmarks|experiments)\b"
    r"|python3? benchmarks/\S+\.py\b)"
)
#: a statement of how long a run takes
TIME = re.compile(
    r"\d+(?:[.,]\d+)?(?:\s*[–-]\s*\d+(?:[.,]\d+)?)?\s*(?:s|sec|seconds?|min|minutes?|h|hours?)\b"
    r"|\b(?:a|one|two|half a) (?:minute|minutes|hour|hours)\b|\bseconds\b",
    re.I,
)
PLACEHOLDERS = {"ID": "attitude_envs/ReactionWheel-v0", "N": "2", "S": "0", "YAML": "{}"}


@dataclass(frozen=True)
class Command:
    page: str  # path relative to the repository root
    line: int  # 1-based line of the command (inline: where the span starts)
    text: str  # the command, continuations joined
    context: str  # where its time statement may stand
    inline: bool

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"


def doc_pages() -> list[Path]:
    pages = [ROOT / "README.md"]
    for p in sorted((ROOT / "docs").rglob("*.md")):
        rel = p.relative_to(ROOT / "docs").parts
        if rel[0] in GENERATED_DIRS or (rel[0] == "campaigns" and rel[-1] == "report.md"):
            continue
        pages.append(p)
    return pages


def _split_commands(line: str) -> list[str]:
    """The commands of one (joined) shell line, without their comments."""
    cut = _comment_start(line)
    code = line if cut is None else line[:cut]
    found = []
    for part in re.split(r"\s(?:&&|;|\|\|)\s", code):
        m = START.search(part)
        if m:
            found.append(part[m.start() :].strip())
    return found


def _comment_start(line: str) -> int | None:
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return i
    return None


def _block_commands(page: str, text: str) -> list[Command]:
    found = []
    for m in SHELL_BLOCK.finditer(text):
        first = text.count("\n", 0, m.start()) + 2
        raw = m.group(1).split("\n")
        i = 0
        while i < len(raw):
            start, joined = i, raw[i]
            while joined.rstrip().endswith("\\") and i + 1 < len(raw):
                i += 1
                joined = joined.rstrip()[:-1] + " " + raw[i].strip()
            above = raw[start - 1].strip() if start > 0 else ""
            cut = _comment_start(joined)
            comment = joined[cut:] if cut is not None else ""
            context = comment + ("\n" + above if above.startswith("#") else "")
            for cmd in _split_commands(joined):
                found.append(Command(page, first + start, cmd, context, inline=False))
            i += 1
    return found


def _inline_commands(page: str, text: str) -> list[Command]:
    # blank out the code blocks, keeping the line numbers
    prose = ANY_BLOCK.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    lines = prose.split("\n")
    found = []
    for m in INLINE.finditer(prose):
        span = " ".join(m.group(1).split())
        if not START.match(span):
            continue
        first = prose.count("\n", 0, m.start())
        last = prose.count("\n", 0, m.end())
        context = INLINE.sub(" ", "\n".join(lines[first : last + 2]))  # its line(s) and the next
        found.append(Command(page, first + 1, span, context, inline=True))
    return found


def doc_commands() -> list[Command]:
    commands = []
    for path in doc_pages():
        page = path.relative_to(ROOT).as_posix()
        text = path.read_text(encoding="utf-8")
        commands += _block_commands(page, text) + _inline_commands(page, text)
    return commands


COMMANDS = doc_commands()


def _is_mention(cmd: Command) -> bool:
    """An inline ``attitude-envs SUBCOMMAND`` (``python train.py <cmd>``, ``attitude-envs``): a name,
    not a command."""
    words = cmd.text.split()
    program = 1 if words[0] == "attitude-envs" else 2 if words[1:2] == ["train.py"] else None
    return cmd.inline and program is not None and len(words) <= program + 1


def _arguments(text: str) -> list[str]:
    """The command's arguments after its program, ready for a parser."""
    while True:  # open optional parts whose content is an option: [--jobs N] → --jobs N
        opened = re.sub(r"\[(-[^\[\]]*)\]", r"\1", text)
        if opened == text:
            break
        text = opened
    words = shlex.split(text, comments=True)
    while words and ("=" in words[0] and not words[0].startswith("-")):  # VAR=value prefixes
        words.pop(0)
    if words[0] == "attitude-envs":
        words = words[1:]
    elif words[1] == "-m" or words[1].endswith(".py"):
        words = words[3:] if words[1] == "-m" else words[2:]
    args = []
    for w in words:
        if w in ("...", "…"):
            continue
        if re.fullmatch(r"[\w./:-]+(?:\|[\w./:-]+)+", w):  # a|b|c: the first alternative
            w = w.split("|")[0]
        args.append(PLACEHOLDERS.get(w, w))
    return args


def _module(text: str) -> str | None:
    """The Python module a ``python -m`` / ``python benchmarks/x.py`` command runs (None: the CLI)."""
    words = shlex.split(text, comments=True)
    while "=" in words[0]:
        words.pop(0)
    if words[0] == "attitude-envs" or words[1] == "train.py":
        return None
    if words[1] == "-m":  # a package runs its __main__
        return words[2] + ".__main__" if importlib.util.find_spec(words[2]).submodule_search_locations else words[2]
    return words[1].removesuffix(".py").replace("/", ".")


class _Parsed(BaseException):  # not an Exception: a main() that catches those lets it through
    pass


def _parse_with_module(module_name: str, args: list[str], monkeypatch) -> argparse.ArgumentParser:
    """Parse ``args`` with the module's ``main``; returns the parser it built."""
    module = importlib.import_module(module_name)
    original = argparse.ArgumentParser.parse_args
    used: list[argparse.ArgumentParser] = []

    def parse_then_stop(self, argv=None, namespace=None):
        used.append(self)
        original(self, argv, namespace)
        raise _Parsed

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_then_stop)
    monkeypatch.setattr(sys, "argv", [module_name, *args])
    with pytest.raises(_Parsed):
        if inspect.signature(module.main).parameters:
            module.main(args)
        else:  # a main() that reads sys.argv
            module.main()
    return used[0]


def _seed_count(text: str) -> float:
    m = re.search(r"--seeds[ =](\S+)", text)
    try:
        return len(parse_seeds(m.group(1))) if m else 5
    except ValueError:  # not the seeds syntax: test_doc_command_parses says so
        return float("inf")


def is_known_fast(cmd: Command) -> bool:
    """The docstring's rule."""
    if _is_mention(cmd):
        return True
    text = cmd.text
    words = text.split() + [""]
    sub = words[1] if words[0] == "attitude-envs" else words[2] if words[1] == "train.py" else None
    if re.search(r"(?:^|\s)(?:--help|-h|--quick)(?:\s|$)", text):
        return True
    if sub in ("envs", "demo"):
        return True
    if sub == "benchmark" and re.search(r"--config[ =]quick(?:\s|$)", text):
        return True
    if sub == "evaluate":  # J* of an episode outside the shipped table: ≈ 2 s on this env, minutes on others
        on_wheel = re.search(r"--env[ =]attitude_envs/ReactionWheel-v0(?:\s|$)", text) or "--env" not in text
        return bool(on_wheel) and _seed_count(text) <= 20 and not re.search(r"--policy[ =]mpc\b", text)
    return False


def test_the_docs_have_commands():
    assert len(COMMANDS) >= 40, [c.id for c in COMMANDS]
    assert any(c.text.startswith("attitude-envs benchmark --config quick") for c in COMMANDS)
    assert any(c.inline for c in COMMANDS) and any(not c.inline for c in COMMANDS)


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    return next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices


def _hidden_options(subcommand: str) -> set[str]:
    """The options of a subcommand kept for old command lines but left out of its help."""
    sub = _subcommands().get(subcommand)
    if sub is None:
        return set()
    return {o for a in sub._actions if a.help == argparse.SUPPRESS for o in a.option_strings}


@pytest.mark.parametrize("cmd", COMMANDS, ids=[c.id for c in COMMANDS])
def test_doc_command_parses(cmd: Command, monkeypatch, capsys):
    if _is_mention(cmd):
        words = cmd.text.split()
        name = words[-1] if words[-1] not in ("attitude-envs", "train.py") else None
        if name and not name.startswith("<"):
            assert name in _subcommands(), f"{cmd.id}: `{cmd.text}`: no subcommand {name!r}"
        return
    args = _arguments(cmd.text)
    module = _module(cmd.text)
    if module is None:  # an old name kept hidden (--workers) parses, but the docs show the current one
        hidden = _hidden_options(args[0]) if args else set()
        shown = {a.split("=")[0] for a in args if a.startswith("-")} & hidden
        assert not shown, f"{cmd.id}: `{cmd.text}` shows the hidden (old) option(s) {sorted(shown)}"
    try:
        if module is None:
            build_parser().parse_args(args)
        else:
            _parse_with_module(module, args, monkeypatch)
    except SystemExit as exc:
        error = capsys.readouterr().err.strip().splitlines()
        pytest.fail(f"{cmd.id}: `{cmd.text}` does not parse (exit {exc.code}): {error[-1] if error else ''}")


def _innermost(parser: argparse.ArgumentParser, args: list[str]) -> argparse.ArgumentParser:
    """The (sub)parser that reads the options of ``args``: the subcommands named in it, followed."""
    while True:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        name = next((w for w in args if subs and w in subs[0].choices), None)
        if name is None:
            return parser
        parser, args = subs[0].choices[name], args[args.index(name) + 1 :]


def _parser_of(cmd: Command, args: list[str], monkeypatch) -> argparse.ArgumentParser:
    module = _module(cmd.text)
    top = build_parser() if module is None else _parse_with_module(module, args, monkeypatch)
    return _innermost(top, args)


def _long_options(parser: argparse.ArgumentParser, shown_in_help: bool) -> set[str]:
    return {
        o
        for a in parser._actions
        if not (shown_in_help and a.help == argparse.SUPPRESS)
        for o in a.option_strings
        if o.startswith("--") and o != "--help"
    }


def _shown_options(args: list[str]) -> set[str]:
    return {a.split("=")[0] for a in args if a.startswith("--")}


def is_synopsis(cmd: Command) -> bool:
    return not cmd.inline and re.search(r"\[--?[A-Za-z]", cmd.text) is not None  # an option, not a negative number


PARSED = [c for c in COMMANDS if not _is_mention(c)]


@pytest.mark.parametrize("cmd", PARSED, ids=[c.id for c in PARSED])
def test_doc_command_names_real_options(cmd: Command, monkeypatch):
    args = _arguments(cmd.text)
    parser = _parser_of(cmd, args, monkeypatch)
    unknown = _shown_options(args) - _long_options(parser, shown_in_help=False)
    assert not unknown, (
        f"{cmd.id}: `{cmd.text}` shows {sorted(unknown)}, which `{parser.prog}` has not (argparse may take it "
        f"as an abbreviation); its options: {sorted(_long_options(parser, shown_in_help=True))}"
    )


SYNOPSES = [c for c in COMMANDS if is_synopsis(c)]


def test_the_docs_have_synopses():
    assert any(c.page == "docs/guide/training.md" and c.text.startswith("attitude-envs train ") for c in SYNOPSES)


@pytest.mark.parametrize("cmd", SYNOPSES, ids=[c.id for c in SYNOPSES])
def test_doc_synopsis_lists_every_option(cmd: Command, monkeypatch):
    args = _arguments(cmd.text)
    parser = _parser_of(cmd, args, monkeypatch)
    left_out = _long_options(parser, shown_in_help=True) - _shown_options(args)
    assert not left_out, (
        f"{cmd.id}: the synopsis `{cmd.text}` leaves out {sorted(left_out)} of `{parser.prog}`: "
        "add each as an optional part `[--opt X]`"
    )


@pytest.mark.parametrize("cmd", COMMANDS, ids=[c.id for c in COMMANDS])
def test_doc_command_says_how_long(cmd: Command):
    if is_known_fast(cmd):
        return
    assert TIME.search(cmd.context), (
        f"{cmd.id}: `{cmd.text}` is not known-fast (see this test's docstring) and says nowhere how long it "
        "runs: add a trailing `# ≈ N min on 2 cores` (or a comment line just above it; inline: on its line "
        "or the next), from a measurement or a recorded wall time"
    )
