"""The README and docs/ stay short, true and linked.

- README.md has at most :data:`MAX_README_LINES` lines and starts with the two commands
  (``make figures``, ``make test``), both real Makefile targets;
- the claims block that ``repro.report`` refreshes is present exactly once;
- every relative link (and ``#anchor``) in README.md and docs/*.md resolves;
- every repository path cited in README.md, CONTRIBUTING.md and docs/*.md (in backticks or as a link)
  exists, ``{a,b}`` and ``*`` patterns matching at least one file; the outputs the tools write under
  ``report/`` and the folders git ignores are exempt (:data:`GENERATED`);
- every ``python -m repro.X --flag`` in README.md and docs/*.md names a flag that the parser of
  ``repro.X`` accepts (the parser is captured from the tool's own ``main``), and every documented
  ``--flag a|b`` value is one of its choices (or a name its help lists);
- every README command line ``python -m repro.X ...`` (fenced or inline) is accepted as written by the
  parser of ``repro.X`` (parsed only, nothing run): a removed flag, a refused value or a missing argument fails;
- every ``--flag`` that a tool's ``--help`` names is a flag of some repro tool, and the synopses in each
  tool's module docstring name only flags (and values) of the tool they show;
- no session or issue numbers in README.md, docs/ or the code's comments and docstrings.
"""

from __future__ import annotations

import argparse
import importlib
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"

#: The README is for users; measurements live in docs/.
MAX_README_LINES = 250

#: Folders whose Python files must not cite session or issue numbers.
CODE_DIRS = ("method", "scenes", "experiments", "repro", "defocus_cache", "benchmarks", "tests")

SESSION_OR_ISSUE = re.compile(r"\b(?:session|issue)[- ]?#?\d+", re.IGNORECASE)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
CLI = re.compile(r"python -m repro\.(\w+)")
FLAG = re.compile(r"(?:^|(?<=[\s\[(]))(--?[A-Za-z][\w-]*)")
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)
INLINE_CODE = re.compile(r"`([^`]+)`")
ALTERNATIVES = re.compile(r"(--[\w-]+)[ =](\w+(?:\|\w+)+)(?![\w.])")


def _markdown_files() -> list[Path]:
    return [README, *sorted(DOCS.glob("*.md"))]


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


# --------------------------------------------------------------------------------------------
# README shape
# --------------------------------------------------------------------------------------------
def test_readme_is_short():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_README_LINES, f"README.md has {n} lines; at most {MAX_README_LINES} (move details to docs/)"


def test_the_two_commands_come_first_and_are_make_targets():
    text = README.read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert lines[0].startswith("# "), "README starts with its title"
    assert lines[1].startswith("```"), "the first thing after the title is the commands' code block"
    assert lines[2].split("#")[0].split() == ["make", "figures"]
    assert lines[3].split("#")[0].split() == ["make", "test"]
    assert lines[4].startswith("```")
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), flags=re.MULTILINE))
    assert {"figures", "test"} <= targets


def test_claims_block_is_there_once_for_the_report_to_refresh():
    from repro.report import README_END, README_START

    text = README.read_text(encoding="utf-8")
    assert text.count(README_START) == 1 and text.count(README_END) == 1
    assert text.index(README_START) < text.index(README_END)


# --------------------------------------------------------------------------------------------
# links
# --------------------------------------------------------------------------------------------
def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces → '-'."""
    text = re.sub(r"[`*]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = FENCE.sub("", path.read_text(encoding="utf-8"))
    return {_slug(m) for m in re.findall(r"^#{1,6}\s+(.*?)\s*#*\s*$", text, flags=re.MULTILINE)}


def _links():
    for md in _markdown_files():
        text = FENCE.sub("", md.read_text(encoding="utf-8"))
        for target in LINK.findall(text):
            if re.match(r"^[a-z]+:", target):  # http:, https:, mailto:
                continue
            yield md, target


def test_the_slug_rule_matches_github_on_known_headings():
    assert _slug("The time targets met (2026-12-02, ≈ 02:45 UTC)") == "the-time-targets-met-2026-12-02--0245-utc"
    assert _slug("Eq. (3) grids and robust's detector scales") == "eq-3-grids-and-robusts-detector-scales"
    assert _slug("`repro.sweep` on a cluster") == "reprosweep-on-a-cluster"


@pytest.mark.parametrize("md,target", list(_links()), ids=lambda v: v if isinstance(v, str) else _rel(v))
def test_every_relative_link_resolves(md, target):
    file_part, _, anchor = target.partition("#")
    dest = (md.parent / file_part).resolve() if file_part else md
    assert dest.exists(), f"{_rel(md)} links to {target}, which does not exist"
    if anchor and dest.suffix == ".md":
        assert anchor in _anchors(dest), f"{_rel(md)} links to {target}: no heading with that anchor"


def test_the_link_check_finds_links():
    found = {(_rel(md), t) for md, t in _links()}
    assert ("README.md", "docs/README.md") in found and len(found) > 20


# --------------------------------------------------------------------------------------------
# cited repository paths
# --------------------------------------------------------------------------------------------
#: Top-level folders of the repository: a cited path starting with one of them must exist.
TOP_FOLDERS = ("method", "scenes", "experiments", "repro", "tests", "docs", "benchmarks", "defocus_cache",
               "report", ".ci", "notes")
#: Paths the tools or the tests write (not in git): cited as where an output goes. Each is written by the
#: module named (checked below, so the list cannot outlive the code that writes them).
GENERATED = {
    "report/figures/": "repro/figures.py",            # python -m repro.figures (default --out)
    "report/quick": "repro/_report_paths.py",         # exploratory runs (git-ignored; default --out of
                                                      # repro.figures --quick and repro.evaluate)
    "report/leaderboard.json": "repro/report.py",      # python -m repro.report --external
    "tests/_failures/": "tests/test_render_reference.py",  # images of a failed comparison (git-ignored)
}
#: Cited paths that are folders of every checkout but never committed (build and cache products).
IGNORED_PARTS = ("__pycache__",)
PATH = re.compile(r"(?<![\w./-])((?:%s)/[\w./*{},-]*)" % "|".join(map(re.escape, TOP_FOLDERS)))


def _spans(text: str) -> list[str]:
    """Inline code spans and link targets of Markdown ``text`` (fenced blocks: commands, not citations)."""
    prose = FENCE.sub("", text)
    spans = [span for para in re.split(r"\n\s*\n", prose) for span in INLINE_CODE.findall(para)]
    return spans + LINK.findall(prose)


def _expand(pattern: str) -> list[str]:
    """``a/{b,c}.md`` -> ``["a/b.md", "a/c.md"]`` (one level of braces, as the docs write them)."""
    m = re.search(r"\{([^{}]*)\}", pattern)
    if not m:
        return [pattern]
    return [x for alt in m.group(1).split(",") for x in _expand(pattern[:m.start()] + alt + pattern[m.end():])]


def _cited_paths():
    out = set()
    for md in [README, ROOT / "CONTRIBUTING.md", *sorted(DOCS.glob("*.md"))]:
        for span in _spans(md.read_text(encoding="utf-8")):
            for path in PATH.findall(span):
                out.add((_rel(md), path.rstrip(".,:;/") + ("/" if path.rstrip(".,:;").endswith("/") else "")))
    return sorted(out)


def _path_exists(path: str) -> bool:
    if any(path.startswith(prefix) for prefix in GENERATED) or any(p in path.split("/") for p in IGNORED_PARTS):
        return True
    for one in _expand(path):
        if any(c in one for c in "*?["):
            if not list(ROOT.glob(one.rstrip("/"))):
                return False
        elif not (ROOT / one).exists():
            return False
    return True


def test_the_path_check_finds_and_refuses_paths():
    found = _cited_paths()
    assert ("CONTRIBUTING.md", "tests/test_architecture.py") in found and len(found) > 100
    assert _path_exists("method/propagation/defocus.py") and not _path_exists("method/propagation/defocus/defocus.py")
    assert _path_exists("report/bench/bench.{md,json}") and not _path_exists("report/bench/bench.{md,xlsx}")
    assert _path_exists("tests/golden/*.json") and not _path_exists("tests/golden/*.xlsx")
    assert _path_exists("report/figures/fig7.png")  # written by repro.figures
    assert _spans("a `x/y.py` b\n\n```\n`c/d.py`\n```\n[l](e/f.md)") == ["x/y.py", "e/f.md"]


@pytest.mark.parametrize("generated, writer", sorted(GENERATED.items()))
def test_generated_paths_are_written_by_their_module(generated, writer):
    text = (ROOT / writer).read_text(encoding="utf-8")
    assert generated.rstrip("/").split("/")[-1] in text, f"{writer} no longer writes {generated}"


@pytest.mark.parametrize("md,path", _cited_paths())
def test_every_cited_path_exists(md, path):
    assert _path_exists(path), f"{md} cites {path}, which is not in the repository"


# --------------------------------------------------------------------------------------------
# documented CLI flags
# --------------------------------------------------------------------------------------------
class _Captured(Exception):
    def __init__(self, parser):
        super().__init__("parser captured")
        self.parser = parser


_PARSERS: dict[str, argparse.ArgumentParser] = {}


def _parser_of(tool: str) -> argparse.ArgumentParser:
    """The ``ArgumentParser`` that ``repro.<tool>.main`` builds, captured at its ``parse_args``."""
    if tool not in _PARSERS:
        module = importlib.import_module(f"repro.{tool}")
        original = argparse.ArgumentParser.parse_args

        def capture(self, *args, **kwargs):
            raise _Captured(self)

        argparse.ArgumentParser.parse_args = capture
        try:
            module.main([])
        except _Captured as c:
            _PARSERS[tool] = c.parser
        finally:
            argparse.ArgumentParser.parse_args = original
        assert tool in _PARSERS, f"repro.{tool}.main did not build a parser"
    return _PARSERS[tool]


def _accepted(tool: str) -> set[str]:
    return {s for a in _parser_of(tool)._actions for s in a.option_strings}


def _flags_after(text: str) -> set[str]:
    return set(FLAG.findall(text.split(" #")[0]))


def _alternatives_after(text: str) -> set[tuple[str, str]]:
    """(flag, value) for every ``--flag a|b|c`` (names only) written in ``text``."""
    out = set()
    for flag, values in ALTERNATIVES.findall(text.split(" #")[0]):
        out |= {(flag, v) for v in values.split("|")}
    return out


def _documented_flags():
    """(file, tool, flag) for every flag written after ``python -m repro.X`` in a command, and in the
    README's per-tool bullets (``- `repro.X` / `repro.Y`: `--a`, ...``: a flag of any tool named)."""
    out = set()
    for md in _markdown_files():
        text = md.read_text(encoding="utf-8")
        commands = []
        for block in FENCE.findall(text):
            commands += block.replace("\\\n", " ").splitlines()
        prose = FENCE.sub("", text)
        commands += [span.replace("\n", " ") for span in INLINE_CODE.findall(prose)]
        for cmd in commands:
            parts = CLI.split(cmd)  # [before, tool1, rest1, tool2, rest2, ...]
            for tool, rest in zip(parts[1::2], parts[2::2]):
                out |= {(_rel(md), (tool,), f) for f in _flags_after(rest)}
                out |= {(_rel(md), (tool,), f"{f} {v}") for f, v in _alternatives_after(rest)}
        for bullet in re.findall(r"^- (`repro\.\w+`(?: / `repro\.\w+`)*:.*?)(?=^- |^\s*$)", prose,
                                 flags=re.MULTILINE | re.DOTALL):
            head, _, body = bullet.partition(":")
            tools = tuple(re.findall(r"repro\.(\w+)", head))
            for span in INLINE_CODE.findall(body):
                if not CLI.search(span):
                    out |= {(_rel(md), tools, f) for f in _flags_after(" " + span)}
                    out |= {(_rel(md), tools, f"{f} {v}") for f, v in _alternatives_after(" " + span)}
    return sorted(out)


def test_the_flag_check_finds_flags():
    found = _documented_flags()
    assert ("README.md", ("evaluate",), "--scene-size") in found
    assert any(tools == ("estimate", "magnify") for _, tools, _ in found)


@pytest.mark.parametrize("md,tools,flag", _documented_flags())
def test_every_documented_flag_exists(md, tools, flag):
    if any(_ok(t, flag) for t in tools):
        return
    raise AssertionError(f"{md} documents {flag} for {' / '.join('repro.' + t for t in tools)}, "
                         "which its parser does not accept")


def _ok(tool: str, flag: str) -> bool:
    """``flag`` is an option of ``repro.<tool>``; ``"--flag value"``: also ``value`` is one of its
    argparse choices or, for options validated later, a word of its help text (registry names)."""
    flag, _, value = flag.partition(" ")
    if flag not in _accepted(tool):
        return False
    if not value:
        return True
    action = next(a for a in _parser_of(tool)._actions if flag in a.option_strings)
    if action.choices is not None:
        return value in {str(c) for c in action.choices}
    return re.search(rf"(?<![\w-]){re.escape(value)}(?![\w-])", action.help or "") is not None


def test_a_made_up_flag_is_caught():
    assert _ok("evaluate", "--scene-size") and not _ok("evaluate", "--no-such-flag")
    assert not _ok("render", "--scene-seed") and _ok("render", "--scene-size")
    assert _ok("render", "--scene-size small") and _ok("evaluate", "--scene-size full")
    assert _ok("magnify", "--kernel disk") and _ok("estimate", "--preset zhuo_sim")
    assert not _ok("evaluate", "--preset small") and not _ok("magnify", "--kernel box")


def _hidden(tool: str, flag: str) -> bool:
    """``flag`` is an old name ``repro.<tool>`` still accepts but no longer shows (``argparse.SUPPRESS``)."""
    return any(flag in a.option_strings and a.help == argparse.SUPPRESS for a in _parser_of(tool)._actions)


@pytest.mark.parametrize("md,tools,flag", _documented_flags())
def test_docs_use_the_current_flag_names(md, tools, flag):
    name = flag.partition(" ")[0]
    hidden = [t for t in tools if _hidden(t, name)]
    assert not hidden, f"{md} documents {name} for repro.{hidden[0]}: an old name kept as a hidden alias"


def test_the_old_name_check_catches_one():
    assert _hidden("render", "--preset") and _hidden("sweep", "--scene-preset") and _hidden("sweep", "--no-progress")
    assert not _hidden("render", "--scene-size") and not _hidden("estimate", "--preset")


#: ``python -m repro.<tool> ARGS``: the tool (lower case: ``repro.X`` is a placeholder) and its arguments.
COMMAND = re.compile(r"python -m repro\.([a-z_]+)\b(.*)")
#: Where a shell command line ends before its comment: a pipe, a redirection, ``&&``, ``||`` or ``;``.
SHELL_END = re.compile(r"\s(?:&&|\|\|?|;|>)\s")


def _readme_commands():
    """(command, tool, argv) of every ``python -m repro.<tool> ...`` of README.md: the lines of its fenced
    blocks and its inline code spans (the arguments split as a shell would, the ``#`` comment dropped)."""
    text = README.read_text(encoding="utf-8")
    lines = [ln for block in FENCE.findall(text) for ln in block.replace("\\\n", " ").splitlines()]
    lines += [span.replace("\n", " ") for span in INLINE_CODE.findall(FENCE.sub("", text))]
    out = []
    for line in lines:
        if m := COMMAND.search(line):
            out.append((" ".join(line.split()), m.group(1), shlex.split(SHELL_END.split(m.group(2))[0], comments=True)))
    return out


def _parse_error(tool: str, argv: list[str]) -> str | None:
    """None if the parser of ``repro.<tool>`` accepts ``argv`` (parsed only, nothing run); else its message."""
    from repro._cli import CLIError

    try:
        _parser_of(tool).parse_args(argv)
    except (CLIError, SystemExit) as exc:  # the tools' parsers raise CLIError; --help and a plain parser exit
        return f"{type(exc).__name__}: {exc}"
    return None


def test_the_readme_command_check_finds_commands_and_refuses_bad_ones():
    found = _readme_commands()
    tools = {tool for _, tool, _ in found}
    assert {"estimate", "magnify", "render", "evaluate", "compare", "bench", "sweep", "dataset", "warmup"} <= tools
    assert any(tool == "magnify" and "--highlights" in argv for _, tool, argv in found)
    assert all("#" not in " ".join(argv) for _, _, argv in found)  # comments dropped
    assert _parse_error("magnify", ["photo.jpg", "--factor", "2", "--highlights"]) is None
    assert "--no-such-flag" in _parse_error("magnify", ["photo.jpg", "--no-such-flag"])  # a removed flag
    assert _parse_error("render", ["portrait_garden", "--scene-size", "huge"])          # a value not allowed
    assert _parse_error("estimate", ["-o", "map.exr"])                                 # the photo missing
    assert _parse_error("estimate", ["photo.jpg", "--encoding", "gamma9"])


@pytest.mark.parametrize("command,tool,argv", _readme_commands(), ids=lambda v: v if isinstance(v, str) else None)
def test_every_readme_command_parses(command, tool, argv):
    """Each README command line, as written, is accepted by its tool's parser (a removed or renamed flag, a
    value its choices refuse, a missing argument fail here)."""
    error = _parse_error(tool, argv)
    assert error is None, f"README.md: `{command}`: repro.{tool}'s parser refuses it: {error}"


def _tools() -> list[str]:
    from repro._cli import COMMANDS

    return sorted(COMMANDS)


def _parsers_with_subcommands(tool: str) -> list[argparse.ArgumentParser]:
    parser = _parser_of(tool)
    return [parser, *(sub for a in parser._actions if isinstance(a, argparse._SubParsersAction)
                      for sub in a.choices.values())]


def _help_text(tool: str) -> str:
    """What ``repro.<tool> --help`` prints (its sub-commands' too): description, epilog and every shown option's
    help, unwrapped (the printed page breaks a long flag at its hyphen)."""
    texts = [t for p in _parsers_with_subcommands(tool)
             for t in (p.description, p.epilog, *(a.help for a in p._actions)) if t and t != argparse.SUPPRESS]
    return "\n".join(texts)


def _accepted_with_subcommands(tool: str) -> set[str]:
    return {s for p in _parsers_with_subcommands(tool) for a in p._actions for s in a.option_strings}


def _usage_lines(tool: str) -> list[tuple[str, str]]:
    """(tool named, its arguments) of each ``python -m repro.<tool> ...`` synopsis in ``repro/<tool>.py``'s
    docstring (a span in double backquotes, or a line of a literal block)."""
    doc = importlib.import_module(f"repro.{tool}").__doc__ or ""
    spans = [" ".join(m.split()) for m in re.findall(r"``(python -m repro\.[a-z_]+[^`]*)``", doc)]
    spans += [ln.strip() for ln in doc.splitlines() if ln.strip().startswith("python -m repro.")]
    return [(m.group(1), m.group(2)) for span in spans for m in [COMMAND.match(span)] if m]


def _flags_no_tool_accepts(text: str) -> list[str]:
    anyone = set().union(*(_accepted_with_subcommands(t) for t in _tools()))
    return sorted({f for f in FLAG.findall(text) if f.startswith("--")} - anyone)


@pytest.mark.parametrize("tool", _tools())
def test_every_flag_a_tools_help_names_exists(tool):
    """``repro.<tool> --help`` names only flags of that tool or of another repro tool (it may point at one),
    and the synopses of its module docstring only flags of the tool they name, with allowed values."""
    ours = _accepted_with_subcommands(tool)
    unknown = _flags_no_tool_accepts(_help_text(tool))
    assert not unknown, f"repro.{tool} --help names {', '.join(unknown)}, which no repro tool accepts"
    for named, rest in _usage_lines(tool):
        flags = _flags_after(rest) | {f"{f} {v}" for f, v in _alternatives_after(rest)}
        bad = sorted(f for f in flags if not (_ok(named, f) or (named == tool and f.partition(" ")[0] in ours
                                                               and " " not in f)))
        assert not bad, f"repro/{tool}.py's docstring shows python -m repro.{named} {' / '.join(bad)}: not accepted"


def test_the_help_check_finds_synopses_and_flags():
    assert "--highlights" in _flags_after(next(rest for t, rest in _usage_lines("magnify") if t == "magnify"))
    assert any(t == "render" and "--list" in rest for t, rest in _usage_lines("render"))  # a literal-block line
    assert "--scenes" in _accepted_with_subcommands("dataset")                            # a sub-command's flag
    assert "--map" in _help_text("magnify") and "--encoding" in _help_text("magnify")
    assert _flags_no_tool_accepts("as repro.evaluate --maps reads it, or --factor 2") == []
    assert _flags_no_tool_accepts("with --highlight-gain G") == ["--highlight-gain"]       # a removed flag
    assert not _ok("magnify", "--floor median") and _ok("magnify", "--floor auto")


# --------------------------------------------------------------------------------------------
# no session or issue numbers
# --------------------------------------------------------------------------------------------
def _texts():
    files = [README, *sorted(DOCS.glob("*.md"))]
    for d in CODE_DIRS:
        files += sorted(p for p in (ROOT / d).rglob("*.py") if ".venv" not in p.parts)
    return [p for p in files if p.resolve() != Path(__file__).resolve()]


@pytest.mark.parametrize("path", _texts(), ids=_rel)
def test_no_session_or_issue_numbers(path):
    hits = [f"{i}: {ln.strip()[:100]}" for i, ln in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
            if SESSION_OR_ISSUE.search(ln)]
    assert not hits, f"{_rel(path)} cites session/issue numbers (say what and why, dates in docs/):\n" + "\n".join(hits)


def test_the_session_check_catches_one():
    assert SESSION_OR_ISSUE.search("measured in session 7") and SESSION_OR_ISSUE.search("issue 11's targets")
    assert not SESSION_OR_ISSUE.search("a full test session") and not SESSION_OR_ISSUE.search("start_new_session=True")
