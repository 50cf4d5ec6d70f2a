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

``run_cli`` catches :data:`USER_ERRORS` (``ValueError``, :class:`CLIError`, the argparse errors of
:class:`ArgumentParser`, :class:`scenes.backend.BackendError`) and the failures of the machine a user
can cause (``OSError``: unwritable folder, disk full; ``MemoryError``) and prints
``PROG: error: MESSAGE`` as a single line, with no traceback; any other exception is a bug and
propagates.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from scenes.backend import VARIANT_ENV, BackendError

__all__ = [
    "USER_ERRORS",
    "ArgumentParser",
    "CLIError",
    "add_variant_option",
    "check_output_path",
    "float_type",
    "int_type",
    "parse_resolution",
    "run_cli",
]


class CLIError(ValueError):
    """A user error detected by a command-line tool (bad flag, unwritable output, ...)."""


#: Exceptions reported as one line + exit status 2.
USER_ERRORS: tuple[type[BaseException], ...] = (ValueError, CLIError, BackendError)


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose usage errors raise :class:`CLIError` (one line, exit 2)
    instead of printing the usage block."""

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
        ``main``'s status, 2 on a user error, 130 on Ctrl-C.
    """
    prog = prog or Path(sys.argv[0]).name or "repro"
    try:
        status = main(argv)
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


def check_output_path(path, *, suffixes: Sequence[str] = (".exr",), flag: str = "--out") -> Path:
    """Check that ``path`` can be written (existing writable folder, allowed suffix, not a folder).

    Nothing is created. Raises :class:`CLIError` naming the path and what is allowed.
    """
    p = Path(path).expanduser()
    if p.suffix.lower() not in tuple(s.lower() for s in suffixes):
        raise CLIError(f"{flag} {str(path)!r} is invalid; allowed: a file name ending in {' or '.join(suffixes)}")
    if p.is_dir():
        raise CLIError(f"{flag} {str(path)!r} is a folder; allowed: a file path in a writable folder")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise CLIError(
            f"{flag} {str(path)!r} is not writable: folder {str(folder)!r} does not exist; "
            "allowed: a file path in an existing writable folder"
        )
    if not os.access(folder, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise CLIError(f"{flag} {str(path)!r} is not writable; allowed: a file path in a writable folder")
    return p
