"""Shared command-line plumbing: user errors become one line on stderr and exit status 2.

Usage in a ``python -m repro.X`` module::

    from repro._cli import ArgumentParser, add_variant_option, run_cli

    def main(argv=None) -> int:
        parser = ArgumentParser(prog="python -m repro.X", description="...")
        add_variant_option(parser)
        args = parser.parse_args(argv)
        ...          # raise ValueError("x=3 is invalid; allowed: ...") on bad input
        return 0

    if __name__ == "__main__":
        sys.exit(run_cli(main, prog="python -m repro.X"))

Every :class:`ArgumentParser` has ``--version``; :func:`add_quiet_option` and :func:`add_force_option`
give the flags shared by the tools one name each (``-q/--quiet``, ``--force``). :func:`console_main` is
the ``defocus-repro`` console script (``defocus-repro figures|render|evaluate|...``): it imports the
sub-command's module ``repro.<name>`` only when asked for it and runs its ``main``.

``run_cli`` catches :data:`USER_ERRORS` (``ValueError``, :class:`CLIError`, the argparse errors of
:class:`ArgumentParser`, :class:`scenes.backend.BackendError`) and the failures of the machine a user
can cause (``OSError``: unwritable folder, disk full; ``MemoryError``) and prints
``PROG: error: MESSAGE`` as a single line, with no traceback; any other exception is a bug and
propagates.

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
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

from scenes.backend import VARIANT_ENV, BackendError

__all__ = [
    "COMMANDS",
    "COMMAND_EXTRAS",
    "EXTRAS",
    "USER_ERRORS",
    "ArgumentParser",
    "CLIError",
    "MissingExtraError",
    "add_force_option",
    "add_quiet_option",
    "add_variant_option",
    "check_output_path",
    "check_scene_names",
    "console_main",
    "float_type",
    "int_type",
    "missing_extra",
    "parse_resolution",
    "require_extras",
    "run_cli",
    "scene_grid",
    "version_string",
]

#: Console-script name (pyproject ``[project.scripts]``).
SCRIPT = "defocus-repro"

#: Sub-commands of ``defocus-repro``: name -> one-line description. Each is the module ``repro.<name>``
#: with a ``main(argv) -> int``, imported only when it runs.
COMMANDS: dict[str, str] = {
    "figures": "compute the paper's figures and their metrics (report/figures)",
    "render": "render a scene with its ground truth (Mitsuba 3, cached)",
    "evaluate": "compare blur estimators against the rendered ground truth",
    "estimate": "estimate the defocus map of a photo",
    "magnify": "magnify the defocus of a photo",
    "report": "write the report (claims and figures) from the figures' metrics",
    "bench": "time each stage and the whole pipeline, with peak memory",
    "sweep": "run a parameter sweep over scenes, cameras and presets",
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


class CLIError(ValueError):
    """A user error detected by a command-line tool (bad flag, unwritable output, ...)."""


class MissingExtraError(CLIError):
    """A command needs a pip extra (:data:`EXTRAS`) that is not installed."""


#: Exceptions reported as one line + exit status 2.
USER_ERRORS: tuple[type[BaseException], ...] = (ValueError, CLIError, BackendError)


#: The pip extras of pyproject.toml's ``[project.optional-dependencies]`` (``all`` = every one, ``test``
#: aside): name -> the top-level modules it installs. The core dependencies install none of them.
EXTRAS: dict[str, tuple[str, ...]] = {
    "render": ("mitsuba", "drjit"),                 # Mitsuba 3 renders (scenes.render_scene)
    "sweep": ("dask", "distributed", "pyarrow"),    # the sweep engine and its Parquet tables
}

#: Extras a command needs whatever its flags: its module -> extra names (checked by :func:`run_cli`).
#: ``repro.estimate``, ``repro.magnify``, ``repro.report`` and ``repro.bench`` (without ``--accuracy``
#: or ``--sweep``) need none; ``repro.evaluate`` checks the render extra itself (``--maps --dataset``
#: needs none).
COMMAND_EXTRAS: dict[str, tuple[str, ...]] = {
    "repro.render": ("render",),
    "repro.figures": ("render",),
    "repro.sweep": ("sweep", "render"),
}

#: How to install an extra, from the checkout (editable, as the README installs the project).
INSTALL_HINT = "pip install -e '.[{extra}]'"


def _installed(module: str) -> bool:
    """True when the top-level ``module`` can be imported (found on the path; not imported here)."""
    import importlib.util

    if module in sys.modules:
        return sys.modules[module] is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing_extra(module: str | None) -> str | None:
    """The extra of :data:`EXTRAS` that installs the (dotted) ``module``, or None if no extra does."""
    top = (module or "").split(".")[0]
    return next((extra for extra, modules in EXTRAS.items() if top in modules), None)


def require_extras(*extras: str, command: str) -> None:
    """Raise :class:`MissingExtraError` (one line naming the extra) unless every module of ``extras`` imports.

    Parameters
    ----------
    *extras : str
        Keys of :data:`EXTRAS`.
    command : str, keyword-only
        What needs them, for the message (``"repro.bench --sweep"``).

    Raises
    ------
    ValueError
        For an extra that is not a key of :data:`EXTRAS`.
    MissingExtraError
        ``"COMMAND needs the 'EXTRA' extra (MODULE is not installed): pip install -e '.[EXTRA]'"``.
    """
    for extra in extras:
        if extra not in EXTRAS:
            raise ValueError(f"unknown extra {extra!r}; allowed: {', '.join(EXTRAS)}")
        for module in EXTRAS[extra]:
            if not _installed(module):
                raise MissingExtraError(_extra_message(command, extra, module))


def _command_of(main) -> str | None:
    """The module name of a command's ``main`` (``repro.render``; also when run as ``python -m``)."""
    module = getattr(main, "__module__", None)
    if module == "__main__":
        spec = getattr(sys.modules.get("__main__"), "__spec__", None)
        module = getattr(spec, "name", None)
    return module


def _extra_message(command: str, extra: str, module: str) -> str:
    return f"{command} needs the {extra!r} extra ({module} is not installed): {INSTALL_HINT.format(extra=extra)}"


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose usage errors raise :class:`CLIError` (one line, exit 2)
    instead of printing the usage block."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.add_argument("--version", action="version", version=version_string(),
                          help="print the version and exit")

    def error(self, message):  # noqa: D102 - argparse hook
        raise CLIError(message)


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
    """
    prog = prog or Path(sys.argv[0]).name or "repro"
    command = _command_of(main) or prog
    args = sys.argv[1:] if argv is None else list(argv)
    with _ctrl_c_redelivered():
        return _run_main(main, argv, args, prog=prog, command=command)


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
        print(f"{prog}: error: {_extra_message(command, extra, exc.name.split('.')[0])}", file=sys.stderr)
        return 2
    except USER_ERRORS as exc:
        print(f"{prog}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"{prog}: error: out of memory (try a smaller image or working resolution)", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        print(f"{prog}: error: {_one_line(exc.strerror or exc)}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
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


def int_type(name: str, *, minimum: int = 1) -> Callable[[str], int]:
    """argparse ``type=`` for an integer ≥ ``minimum`` (argparse prefixes the flag ``name`` to errors)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: integer >= {minimum}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: integer >= {minimum}")
        return value

    return parse


def float_type(name: str, *, positive: bool = True) -> Callable[[str], float]:
    """argparse ``type=`` for a finite (positive) float (argparse prefixes the flag ``name`` to errors)."""
    import math

    allowed = "finite number > 0" if positive else "finite number"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: {allowed}") from None
        if not math.isfinite(value) or (positive and value <= 0):
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: {allowed}")
        return value

    return parse


def parse_resolution(text: str) -> tuple[int, int]:
    """``"640x480"`` → (640, 480); raises :class:`CLIError` naming the value and the format."""
    parts = str(text).lower().split("x")
    allowed = "WxH with positive integers, e.g. 640x480"
    if len(parts) != 2:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}")
    try:
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}") from None
    if w <= 0 or h <= 0:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}")
    return w, h


def check_output_path(path, *, suffixes: Sequence[str] = (".exr",), flag: str = "--out", photo=None,
                      overwrite: bool = False) -> Path:
    """Refuse an output path before any work; nothing is left behind.

    Parameters
    ----------
    path : str or Path
        Where the output will be written (``~`` expanded).
    suffixes : sequence of str, keyword-only
        Allowed extensions (case-insensitive), e.g. ``(".exr", ".png", ".npy")``.
    flag : str, keyword-only
        How the output is named in messages (``"--out"``, ``"output map"``, ``"--save-map"``).
    photo : str or Path, optional, keyword-only
        The input photo: an output may replace it only with ``overwrite``.
    overwrite : bool, keyword-only
        Allow ``path`` to be ``photo``.

    Returns
    -------
    Path
        ``path`` with ``~`` expanded.

    Raises
    ------
    CLIError
        Naming the path and what is allowed: bad extension, a folder, a missing or unwritable folder
        (a real probe file, so read-only mounts and ACLs that ``os.access`` misses are caught too),
        the input photo without ``overwrite``.
    """
    p = Path(path).expanduser()
    shown = f"{flag} {str(path)!r}"
    writable = "allowed: a file path in an existing writable folder"
    if p.suffix.lower() not in tuple(s.lower() for s in suffixes):
        raise CLIError(f"{shown}: extension {p.suffix or '(none)'!r} is not supported; "
                       f"allowed: a file name ending in {', '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.exists():
        raise CLIError(f"{shown} is not writable: folder {str(folder)!r} does not exist; {writable}")
    if not folder.is_dir():
        raise CLIError(f"{shown} is not writable: {str(folder)!r} is not a folder; {writable}")
    if p.is_dir():
        raise CLIError(f"{shown} is a directory; allowed: a file path in a writable folder")
    if not os.access(folder, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise CLIError(f"{shown} is not writable; {writable}")
    if photo is not None and p.exists() and Path(photo).exists() and os.path.samefile(p, photo) and not overwrite:
        raise CLIError(f"{shown} is the input photo; allowed: another path, or --overwrite to replace the photo")
    try:  # a real probe: read-only mounts and ACLs that os.access does not see
        fd, probe = tempfile.mkstemp(prefix=f".{p.name}.probe.", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise CLIError(f"{shown} is not writable: cannot write in {str(folder)!r} ({exc.strerror or exc}); "
                       f"{writable}") from None
    return p


def check_scene_names(names, *, what: str = "scene") -> list[str]:
    """``names`` as a list if each is a scene of :data:`scenes.SCENES` or ``procedural_<seed>[_<camera>]``.

    Raises
    ------
    ValueError
        Naming the unknown ones and the allowed names (the registry's message, plus the procedural form).
    """
    from method.registry import Registry
    from scenes import SCENES
    from scenes.library import is_procedural_name

    names = list(names)
    named = [n for n in names if not is_procedural_name(n)]
    try:
        if named or not names:  # (an empty list is refused by the registry, naming the scenes)
            Registry("scene", SCENES).check_all(named, what=what)
    except ValueError as exc:
        raise ValueError(f"{exc}, or procedural_<seed>") from None
    return names


def scene_grid(scenes, f_numbers, scene_preset: str, *, out=None) -> tuple[list[str], list[float]]:
    """Validated scenes × f-numbers of a render grid, duplicates dropped, before anything is rendered.

    Parameters
    ----------
    scenes : sequence of str or None
        Keys of :data:`scenes.SCENES` (None: all).
    f_numbers : sequence of float
    scene_preset : str
        Render resolution preset.
    out : path, optional, keyword-only
        An output folder, refused when it is a file.

    Raises
    ------
    ValueError
        One line naming the unknown scene(s), the bad f-number, or the ``--out`` that is a file.
    """
    from scenes import SCENES
    from scenes.render import validate_render_options

    names = check_scene_names(dict.fromkeys(scenes or list(SCENES)))
    numbers = list(dict.fromkeys(float(n) for n in f_numbers))
    for s in names:
        for n in numbers:
            validate_render_options(s, preset=scene_preset, f_number=n)  # ValueError on a bad N
    if out is not None and Path(out).exists() and not Path(out).is_dir():
        raise ValueError(f"--out {str(out)!r} is a file; allowed: a folder")
    return names, numbers
