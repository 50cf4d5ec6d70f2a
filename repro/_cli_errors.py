"""What a command-line tool reports as the user's error: :class:`CLIError`, :func:`user_input`, missing extras.

A user error is one line on stderr and exit status 2 (:func:`repro._cli.run_cli`); anything else is a
bug and shows its traceback. The API's validators raise ``ValueError`` (``method``, ``scenes``,
``experiments`` know nothing of command lines); a CLI turns the ones it calls on what the user gave
into :class:`CLIError` with :func:`user_input`, so a ``ValueError`` raised deeper, inside the method,
is never mistaken for a bad flag.

Everything here is re-exported by :mod:`repro._cli`; import it from there.
"""

from __future__ import annotations

import contextlib
import sys

from scenes.backend import BackendError

__all__ = ["COMMAND_EXTRAS", "EXTRAS", "INSTALL_HINT", "USER_ERRORS", "CLIError", "MissingExtraError",
           "extra_message", "missing_extra", "require_extras", "user_input"]


class CLIError(ValueError):
    """A user error detected by a command-line tool (bad flag, file or name; unwritable output, ...).

    A subclass of ``ValueError``, so the helpers that raise it can be called from the API and tests as
    validators (``pytest.raises(ValueError)``); :func:`repro._cli.run_cli` reports it as one line and
    exit status 2.
    """


class MissingExtraError(CLIError):
    """A command needs a pip extra (:data:`EXTRAS`) that is not installed."""


#: Exceptions reported as one line + exit status 2 (``OSError`` and ``MemoryError``, the machine's
#: failures a user can cause, are reported as one line too; see :func:`repro._cli.run_cli`).
#: ``ValueError`` is not one of them: only the ``ValueError`` raised inside :func:`user_input` is.
USER_ERRORS: tuple[type[BaseException], ...] = (CLIError, BackendError)


class user_input(contextlib.ContextDecorator):
    """Context manager (or decorator) around the validation of what the user gave: inside it a
    ``ValueError`` becomes :class:`CLIError` (one line, exit status 2), chained to the original so
    ``--debug`` shows where it was raised.

    Parameters
    ----------
    prefix : str, optional
        Put before the message, e.g. ``"--map"`` gives ``"--map <message>"``.

    Examples
    --------
    >>> with user_input():
    ...     params = DefocusParams.preset(args.preset)         # a bad --preset: one line, exit 2
    >>> @user_input()
    ... def load_photo(args): ...                               # every ValueError of the decoder

    Notes
    -----
    Wrap the calls that validate flags, files and names, not the computation after them: a
    ``ValueError`` raised by the method on input that passed validation is a bug and must show its
    traceback.
    """

    def __init__(self, prefix: str | None = None):
        self.prefix = prefix

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc is None or not isinstance(exc, ValueError) or isinstance(exc, CLIError):
            return False
        message = f"{self.prefix} {exc}" if self.prefix else str(exc)
        raise CLIError(message) from exc


#: The pip extras of pyproject.toml's ``[project.optional-dependencies]`` (``all`` = every one, ``test``
#: aside): name -> the top-level modules it installs. The core dependencies install none of them.
EXTRAS: dict[str, tuple[str, ...]] = {
    "render": ("mitsuba", "drjit"),                 # Mitsuba 3 renders (scenes.render_scene)
    "sweep": ("dask", "distributed", "pyarrow"),    # the sweep engine and its Parquet tables
}

#: Extras a command needs whatever its flags: its module -> extra names (checked by :func:`run_cli`).
#: ``repro.estimate``, ``repro.magnify``, ``repro.report`` and ``repro.bench`` (without ``--accuracy``
#: or ``--sweep``) need none; ``repro.evaluate`` checks the render extra itself (``--maps --dataset``
#: needs none); ``repro.dataset`` needs it only for renders not yet exported.
COMMAND_EXTRAS: dict[str, tuple[str, ...]] = {
    "repro.render": ("render",),
    "repro.figures": ("render",),
    "repro.compare": ("render",),
    "repro.sweep": ("sweep", "render"),
}

#: How to install an extra, from the checkout (editable, as the README installs the project).
INSTALL_HINT = "pip install -e '.[{extra}]'"


def module_installed(module: str) -> bool:
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


def extra_message(command: str, extra: str, module: str) -> str:
    """``"COMMAND needs the 'EXTRA' extra (MODULE is not installed): pip install -e '.[EXTRA]'"``."""
    return f"{command} needs the {extra!r} extra ({module} is not installed): {INSTALL_HINT.format(extra=extra)}"


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
        For an extra that is not a key of :data:`EXTRAS` (a bug of the caller, not a user error).
    MissingExtraError
        ``"COMMAND needs the 'EXTRA' extra (MODULE is not installed): pip install -e '.[EXTRA]'"``.
    """
    for extra in extras:
        if extra not in EXTRAS:
            raise ValueError(f"unknown extra {extra!r}; allowed: {', '.join(EXTRAS)}")
        for module in EXTRAS[extra]:
            if not module_installed(module):
                raise MissingExtraError(extra_message(command, extra, module))
