"""Run a ``python -m repro.X`` command in the test process: ``run_cli(main, argv)`` with stdout/stderr
captured and the environment given, as ``subprocess.run`` would see it, without the ≈ 1.5 s of imports
a new interpreter pays per call.

Each CLI keeps one subprocess smoke test (the real ``python -m`` entry point, its ``__main__`` guard and
exit status); the many bad-input and option tests use :func:`run_in_process`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import io
import os
import sys


@dataclasses.dataclass
class CLIResult:
    """What ``subprocess.run(..., capture_output=True, text=True)`` returns, for an in-process run."""

    returncode: int
    stdout: str
    stderr: str
    args: list


@contextlib.contextmanager
def _environ(env):
    if env is None:
        yield
        return
    saved = dict(os.environ)
    os.environ.clear()
    os.environ.update({k: str(v) for k, v in env.items()})
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def run_in_process(module: str, args, *, env=None) -> CLIResult:
    """``python -m <module> <args>`` in this process: its ``main`` through :func:`repro._cli.run_cli`.

    Parameters
    ----------
    module : str
        ``"repro.render"``, ``"repro.estimate"``, ... (a module with ``main(argv)`` and ``PROG``).
    args : sequence of str or path
        The arguments (``sys.argv[1:]``).
    env : mapping, optional
        The whole environment of the call (as ``subprocess.run(env=...)``); default: unchanged.

    Returns
    -------
    CLIResult
        ``returncode`` (``main``'s status, 2 on a user error, argparse's status on ``--help``/usage errors),
        and the text written to stdout and stderr.
    """
    from repro._cli import run_cli

    mod = importlib.import_module(module)
    argv = [str(a) for a in args]
    prog = getattr(mod, "PROG", f"python -m {module}")
    out, err = io.StringIO(), io.StringIO()
    with _environ(env), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        saved_argv = sys.argv
        sys.argv = [prog, *argv]
        try:
            code = run_cli(mod.main, argv, prog=prog)
        except SystemExit as exc:  # argparse's --help / --version
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        finally:
            sys.argv = saved_argv
    return CLIResult(returncode=code, stdout=out.getvalue(), stderr=err.getvalue(), args=argv)
