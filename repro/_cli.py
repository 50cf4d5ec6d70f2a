"""Shared command-line plumbing: a user error is one line on stderr and exit status 2, a bug shows its traceback.

Usage in a ``python -m repro.X`` module::

    from repro._cli import ArgumentParser, CLIError, add_quiet_option, run_cli, user_input

    def main(argv=None) -> int:
        parser = ArgumentParser(prog="python -m repro.X", description="...")
        add_quiet_option(parser)
        args = parser.parse_args(argv)          # usage errors: CLIError
        with user_input():                      # the API's ValueError on what the user gave: CLIError
            params = DefocusParams.preset(args.preset)
        if args.out.is_file():
            raise CLIError(f"--out {args.out} is a file; allowed: a folder")
        compute(params)                         # a ValueError here is a bug: traceback
        return 0

    if __name__ == "__main__":
        sys.exit(run_cli(main, prog="python -m repro.X"))

Errors. :func:`run_cli` prints ``PROG: error: MESSAGE`` as a single line and returns exit status 2 for
:data:`USER_ERRORS` (:class:`CLIError`, which :class:`ArgumentParser` raises for usage errors and
:func:`user_input` for the ``ValueError`` of a validator it wraps; a missing extra; a
:class:`scenes.backend.BackendError`) and for the failures of the machine a user can cause (``OSError``:
unwritable folder, disk full; ``MemoryError``). Every other exception, a plain ``ValueError``
included, is a bug and propagates with its traceback. ``--debug`` (every :class:`ArgumentParser` has
it) prints the traceback of a user error too, before its line.

Validating input: raise :class:`CLIError` in CLI code; call the API's validators (registry ``check``,
``DefocusParams``, ``validate_render_options``, photo readers, ...) inside ``with user_input():`` (or
decorate a CLI helper that only validates with ``@user_input()``). Wrap only validation, never the
computation that follows. Ready-made validators: :func:`int_type` / :func:`float_type` (argparse
``type=``), :func:`parse_resolution`, :func:`check_output_path`, :func:`check_scene_names`,
:func:`scene_grid` (:mod:`repro._cli_checks`).

Flags with one name in every tool: ``--version`` and ``--debug`` (every :class:`ArgumentParser`),
:func:`add_quiet_option` (``-q/--quiet``), :func:`add_force_option` (``--force``),
:func:`add_variant_option` (``--variant``), :func:`add_scene_size_option` (``--scene-size small|full``,
the render size; ``--scene-preset`` kept as a hidden alias) and :func:`add_preset_option` (``--preset``,
a method parameter set of ``method.PRESETS`` only, with the tool's default stated in its help).
:func:`hidden_alias` adds an old flag name that still works but is not shown.

Estimators and presets of other packages (:mod:`repro._plugins`): :func:`add_plugin_options` adds
``--estimator-module [NAME=]package.module:function`` and ``--preset-module [NAME=]package.module:ATTRIBUTE``
(repeatable) and makes ``parse_args`` register them, after the entry points of the groups
``defocus_repro.estimators`` / ``defocus_repro.presets``, before the tool validates any name; every
Dask worker the tool starts imports the same paths. One call per tool that evaluates the method.

:func:`console_main` is the ``defocus-repro`` console script (``defocus-repro COMMAND``, one per
``repro.X`` tool, :data:`COMMANDS`): it imports the sub-command's module ``repro.<name>`` only when
asked for it and runs its ``main``.

Optional dependencies: the core install (``pip install -e .``) runs ``method`` and the photo tools
(``repro.estimate``, ``repro.magnify``); the renderer and the sweep engine are the pip extras of
:data:`EXTRAS`. A command that needs an extra whatever its flags is listed in :data:`COMMAND_EXTRAS`
and ``run_cli`` checks it before the command runs (``--help`` and ``--version`` work without it);
:func:`require_extras` checks one for a flag (``repro.bench --sweep``). A missing extra is one line
naming it, e.g. ``python -m repro.render: error: repro.render needs the 'render' extra (mitsuba is not
installed): pip install -e '.[render]'``, and exit status 2; so is a ``ModuleNotFoundError`` of one of
their modules raised later (a code path the tables do not list).
"""

from __future__ import annotations

import _thread
import argparse
import contextlib
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path

from scenes.backend import VARIANT_ENV

from repro._cli_checks import (check_output_path, check_scene_names, float_type, int_type, parse_resolution,
                               scene_grid)
from repro._cli_errors import (COMMAND_EXTRAS, EXTRAS, INSTALL_HINT, USER_ERRORS, CLIError, MissingExtraError,
                               extra_message, missing_extra, require_extras, user_input)

__all__ = [
    "COMMANDS",
    "COMMAND_EXTRAS",
    "EXTRAS",
    "INSTALL_HINT",
    "USER_ERRORS",
    "ArgumentParser",
    "CLIError",
    "MissingExtraError",
    "add_force_option",
    "add_plugin_options",
    "add_preset_option",
    "add_quiet_option",
    "add_scene_size_option",
    "add_variant_option",
    "check_output_path",
    "check_scene_names",
    "console_main",
    "float_type",
    "hidden_alias",
    "int_type",
    "missing_extra",
    "parse_resolution",
    "require_extras",
    "run_cli",
    "scene_grid",
    "user_input",
    "version_string",
]

#: Console-script name (pyproject ``[project.scripts]``).
SCRIPT = "defocus-repro"

#: Sub-commands of ``defocus-repro``: name -> one-line description. Each is the module ``repro.<name>``
#: with a ``main(argv) -> int``, imported only when it runs (every ``repro.X`` with a ``main``;
#: ``tests/test_cli.py`` checks the list).
COMMANDS: dict[str, str] = {
    "figures": "compute the paper's figures and their metrics (report/figures)",
    "render": "render a scene with its ground truth (Mitsuba 3, cached)",
    "evaluate": "compare blur estimators against the rendered ground truth",
    "compare": "rank two presets or baselines on the same scenes, with paired confidence",
    "estimate": "estimate the defocus map of a photo",
    "magnify": "magnify the defocus of a photo",
    "report": "write the report (claims and figures) from the figures' metrics",
    "bench": "time each stage and the whole pipeline, with peak memory",
    "sweep": "run a parameter sweep over scenes, cameras and presets",
    "dataset": "export the rendered scenes and their ground truth as a dataset",
    "warmup": "compile every numba kernel of the photo tools into numba's cache (after an install)",
}


def version_string() -> str:
    """``defocus-repro 0.1.0`` (the installed distribution's version; pyproject's in a bare checkout)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version(SCRIPT)
    except PackageNotFoundError:  # pragma: no cover - running from a checkout that was never installed
        import re

        text = (Path(__file__).resolve().parents[1] / "pyproject.toml").read_text()
        m = re.search(r'^version\s*=\s*"([^"]+)"', text, flags=re.M)
        v = m.group(1) if m else "unknown"
    return f"{SCRIPT} {v}"


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with ``--version`` and ``--debug``, whose usage errors raise
    :class:`CLIError` (one line, exit 2) instead of printing the usage block."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.after_parse: list[Callable] = []  # fn(namespace), run after a successful parse (add_plugin_options)
        self.add_argument("--version", action="version", version=version_string(),
                          help="print the version and exit")
        self.add_argument("--debug", action="store_true",
                          help="on any error print the Python traceback (user errors are one line without it)")

    def parse_known_args(self, args=None, namespace=None):  # noqa: D102 - records --debug for run_cli
        namespace, extras = super().parse_known_args(args, namespace)
        if getattr(namespace, "debug", False):
            _DEBUG["on"] = True
        for hook in self.after_parse:
            hook(namespace)
        return namespace, extras

    def error(self, message):  # noqa: D102 - argparse hook
        raise CLIError(message)


#: ``--debug`` seen by an :class:`ArgumentParser` during the current :func:`run_cli` (abbreviations too).
_DEBUG = {"on": False}


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def run_cli(main: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None = None, *,
            prog: str | None = None) -> int:
    """Call ``main(argv)``; turn :data:`USER_ERRORS` into one stderr line and exit status 2.

    Parameters
    ----------
    main : callable
        Takes ``argv`` (list of str or None) and returns an exit status (None means 0).
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``, as argparse does).
    prog : str, optional, keyword-only
        Program name for the message (default: ``sys.argv[0]``'s name).

    Returns
    -------
    int
        ``main``'s status, 2 on a user error or a missing extra (:data:`COMMAND_EXTRAS`), 130 on Ctrl-C.

    Raises
    ------
    Exception
        Any other exception of ``main`` (a bug), unchanged, with its traceback.

    Notes
    -----
    With ``--debug`` in ``argv`` (or parsed by an :class:`ArgumentParser` of ``main``), the traceback of
    a user error, a machine error or a Ctrl-C is printed before its line.
    """
    prog = prog or Path(sys.argv[0]).name or "repro"
    command = _command_of(main) or prog
    args = sys.argv[1:] if argv is None else list(argv)
    saved, _DEBUG["on"] = _DEBUG["on"], False
    try:
        with _ctrl_c_redelivered():
            return _run_main(main, argv, args, prog=prog, command=command)
    finally:
        _DEBUG["on"] = saved


def _command_of(main) -> str | None:
    """The module name of a command's ``main`` (``repro.render``; also when run as ``python -m``)."""
    module = getattr(main, "__module__", None)
    if module == "__main__":
        spec = getattr(sys.modules.get("__main__"), "__spec__", None)
        module = getattr(spec, "name", None)
    return module


#: s after a Ctrl-C swallowed by a callback until it is pressed again (the callback has returned by then).
REDELIVER_CTRL_C_S = 0.05


def _redeliver_ctrl_c(previous, timers: list):
    """An unraisable hook that sends a Ctrl-C swallowed by a callback to the main thread again."""
    def hook(unraisable):
        if (unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt)
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            # Later, from another thread: raised here it would land in this hook and be lost again.
            timer = threading.Timer(REDELIVER_CTRL_C_S, _thread.interrupt_main)
            timer.daemon = True
            timers.append(timer)
            timer.start()
            return
        previous(unraisable)
    return hook


@contextlib.contextmanager
def _ctrl_c_redelivered():
    """While a tool runs, a Ctrl-C is never lost in a callback and never prints a traceback.

    Python raises KeyboardInterrupt at whatever bytecode runs when SIGINT arrives; inside a weakref
    or ``__del__`` callback (Dr.Jit and NumPy run many) the exception cannot propagate, so Python
    prints "Exception ignored in ..." with a traceback and goes on as if no key had been pressed.
    The hook presses Ctrl-C again a moment later instead, which Python answers outside the callback.
    """
    previous, timers = sys.unraisablehook, []
    sys.unraisablehook = _redeliver_ctrl_c(previous, timers)
    try:
        yield
    finally:
        sys.unraisablehook = previous
        for timer in timers:  # the tool has ended: a Ctrl-C still pending must not reach the caller
            timer.cancel()


def _fail(prog: str, message: str, exc: BaseException, args, *, status: int = 2, label: str = "error: ") -> int:
    """Print ``PROG: error: MESSAGE`` (after the traceback with ``--debug``); return ``status``."""
    if _DEBUG["on"] or "--debug" in args[:args.index("--") if "--" in args else len(args)]:
        traceback.print_exception(exc, file=sys.stderr)
    print(f"{prog}: {label}{message}", file=sys.stderr)
    return status


def _run_main(main, argv, args, *, prog, command) -> int:
    """:func:`run_cli`'s body: ``main(argv)`` with every user error turned into one line."""
    try:
        if command in COMMAND_EXTRAS and not {"-h", "--help", "--version"} & set(args):
            require_extras(*COMMAND_EXTRAS[command], command=command)
        status = main(argv)
    except ModuleNotFoundError as exc:  # an extra's module imported on a path the tables do not list
        extra = missing_extra(exc.name)
        if extra is None:
            raise
        return _fail(prog, extra_message(command, extra, exc.name.split(".")[0]), exc, args)
    except USER_ERRORS as exc:
        return _fail(prog, _one_line(exc), exc, args)
    except MemoryError as exc:
        return _fail(prog, "out of memory (try a smaller image or working resolution)", exc, args)
    except OSError as exc:
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        return _fail(prog, f"{_one_line(exc.strerror or exc)}{where}", exc, args)
    except KeyboardInterrupt as exc:
        return _fail(prog, "interrupted", exc, args, status=130, label="")
    return 0 if status is None else int(status)


def add_quiet_option(parser: argparse.ArgumentParser, *, what: str = "no progress display and no notes") -> None:
    """Add ``-q/--quiet`` (dest ``quiet``), the one name of every tool for "print less"."""
    parser.add_argument("-q", "--quiet", action="store_true", help=what)


def add_force_option(parser: argparse.ArgumentParser, *,
                     what: str = "recompute even when a cached result exists (the new result replaces it)") -> None:
    """Add ``--force`` (dest ``force``), the one name of every tool for "do not reuse the cache".

    ``--no-cache``, the earlier name of some tools, is accepted as a hidden synonym.
    """
    parser.add_argument("--force", action="store_true", help=what)
    parser.add_argument("--no-cache", dest="force", action="store_true", help=argparse.SUPPRESS)


def hidden_alias(parser, *flags: str, dest: str, **kwargs) -> None:
    """Add old flag names that still work but are not shown in ``--help`` (``argparse.SUPPRESS``).

    ``kwargs`` are those of the current flag (``choices``, ``type``, ``action``, ...); the alias has no
    default of its own, so the current flag's default stands.
    """
    parser.add_argument(*flags, dest=dest, default=argparse.SUPPRESS, help=argparse.SUPPRESS, **kwargs)


def add_scene_size_option(parser, *, default: str | None = "small", aliases: Sequence[str] = ("--scene-preset",),
                          what: str = "render size") -> None:
    """Add ``--scene-size SIZE`` (dest ``scene_size``): the render size, a key of :data:`scenes.library.PRESETS`.

    Parameters
    ----------
    parser : argparse.ArgumentParser or argument group
    default : str or None, keyword-only
        Stated in the help (None: the tool says what it does without the flag, in ``what``).
    aliases : sequence of str, keyword-only
        Earlier names of the flag, accepted and hidden (:func:`hidden_alias`).
    what : str, keyword-only
        The help's first words.
    """
    from scenes.library import PRESETS

    sizes = ", ".join(f"{name} {w}x{h}" for name, (w, h) in PRESETS.items())
    shown = f"; default {default}" if default is not None else ""
    parser.add_argument("--scene-size", dest="scene_size", default=default, choices=tuple(PRESETS),
                        help=f"{what}: {sizes}{shown}")
    if aliases:
        hidden_alias(parser, *aliases, dest="scene_size", choices=tuple(PRESETS))


def add_preset_option(parser, *, default, many: bool = False, blurbs: dict | None = None, extra: str = "") -> None:
    """Add ``--preset NAME`` (dest ``preset``): a method parameter set of ``method.PRESETS``, default stated.

    Parameters
    ----------
    parser : argparse.ArgumentParser or argument group
    default : str or tuple of str, keyword-only
        The tool's default preset (``many``: presets), named in the help.
    many : bool, keyword-only
        ``--preset NAME [NAME ...]`` (a list) instead of one name.
    blurbs : dict, optional, keyword-only
        One phrase per preset name for the help (default: the registry's summaries).
    extra : str, keyword-only
        Appended to the help.
    """
    from method.presets import PRESETS

    listing = ("; ".join(f"{name} ({blurbs[name]})" if name in blurbs else name for name in PRESETS)
               if blurbs else PRESETS.describe())
    shown = " ".join(default) if many else default
    parser.add_argument("--preset", nargs="+" if many else None, default=list(default) if many else default,
                        metavar="NAME",
                        help=f"method parameter set{'s' if many else ''} (method.PRESETS): {listing}. "
                             f"Default: {shown}{'. ' + extra if extra else ''}")


def add_plugin_options(parser: ArgumentParser) -> None:
    """Add ``--estimator-module`` / ``--preset-module`` (repeatable; dests ``estimator_module``,
    ``preset_module``) and register them, after the installed entry points, when ``parser`` parses.

    A bad spec, a module that does not import, an object of the wrong kind or a taken name is one line
    and exit status 2 (:func:`user_input` around :func:`repro._plugins.load_plugins`).
    """
    from repro._plugins import ENTRY_POINT_GROUPS

    groups = " / ".join(ENTRY_POINT_GROUPS.values())
    parser.add_argument("--estimator-module", action="append", default=[], metavar="[NAME=]PKG.MODULE:FUNCTION",
                        help="register a blur estimator fn(gray, edge_map, *, params) of another package under NAME "
                             "(default: the function's name), here and on every Dask worker; repeatable. Installed "
                             f"packages' entry points ({groups}) are registered without a flag")
    parser.add_argument("--preset-module", action="append", default=[], metavar="[NAME=]PKG.MODULE:ATTRIBUTE",
                        help="register a preset (a method.DefocusParams) of another package under NAME (default: "
                             "the attribute's name); repeatable")

    def load(namespace):
        from repro._plugins import load_plugins

        with user_input():
            load_plugins(namespace.estimator_module, namespace.preset_module)

    parser.after_parse.append(load)


def console_main(argv: Sequence[str] | None = None) -> int:
    """The ``defocus-repro`` console script: ``defocus-repro COMMAND [ARGS...]`` runs ``repro.COMMAND``.

    Parameters
    ----------
    argv : list of str, optional
        Default ``sys.argv[1:]``.

    Returns
    -------
    int
        The sub-command's exit status; 2 for an unknown or missing command (one line on stderr).
    """
    import importlib

    argv = list(sys.argv[1:] if argv is None else argv)
    listing = "\n".join(f"  {name:<9} {text}" for name, text in COMMANDS.items())
    usage = (f"usage: {SCRIPT} COMMAND [ARGS...]   ({SCRIPT} COMMAND --help for its options)\n\n"
             f"commands:\n{listing}\n\nEach command is also `python -m repro.COMMAND`.")
    if not argv:
        print(usage, file=sys.stderr)
        return 2
    if argv[0] in ("-h", "--help"):
        print(usage)
        return 0
    if argv[0] == "--version":
        print(version_string())
        return 0
    name, rest = argv[0], argv[1:]
    from method.registry import Registry

    try:
        Registry("command", COMMANDS).check(name, what="command")
    except ValueError as exc:
        print(f"{SCRIPT}: error: {exc}", file=sys.stderr)
        return 2
    try:
        module = importlib.import_module(f"repro.{name}")
    except ModuleNotFoundError as exc:
        if exc.name != f"repro.{name}":
            raise
        print(f"{SCRIPT}: error: command {name!r} is not available in this installation (no module repro.{name})",
              file=sys.stderr)
        return 2
    return run_cli(module.main, rest, prog=f"{SCRIPT} {name}")


def add_variant_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--variant V``: the Mitsuba variant (default ``$DEFOCUS_MITSUBA_VARIANT`` or auto)."""
    parser.add_argument(
        "--variant",
        default=None,
        metavar="V",
        help=f"Mitsuba variant, e.g. llvm_ad_rgb or scalar_rgb (default: ${VARIANT_ENV}, else the fastest "
        "that works here)",
    )


