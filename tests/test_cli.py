"""repro._cli.run_cli: user and machine errors become one stderr line; bugs propagate."""

import gc
import signal
import sys
import time
import weakref

import pytest

from repro._cli import run_cli


def _raiser(exc):
    def main(argv=None):
        raise exc
    return main


@pytest.mark.parametrize("exc, needle", [
    (ValueError("x=3 is invalid; allowed: > 4"), "x=3 is invalid"),
    (PermissionError(13, "Permission denied", "/root/out.png"), "Permission denied (/root/out.png)"),
    (OSError(28, "No space left on device"), "No space left on device"),
    (MemoryError(), "out of memory"),
])
def test_user_and_machine_errors_are_one_line_exit_2(exc, needle, capsys):
    assert run_cli(_raiser(exc), [], prog="prog") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prog: error: ") and needle in err[0]


def test_ctrl_c_is_exit_130(capsys):
    assert run_cli(_raiser(KeyboardInterrupt()), [], prog="prog") == 130
    assert "interrupted" in capsys.readouterr().err


class _Thing:
    pass


def _ctrl_c_inside_a_callback(argv=None):
    """A Ctrl-C that lands in a weakref callback (where Python cannot raise it), then more work."""
    thing = _Thing()
    ref = weakref.ref(thing, lambda r: (_ for _ in ()).throw(KeyboardInterrupt))
    del thing
    gc.collect()
    deadline = time.monotonic() + 2
    while time.monotonic() < deadline:  # a tool going on with its work: the Ctrl-C must still stop it
        time.sleep(0.01)
    return 0 if ref is not None else 1


def _with_default_sigint(fn):
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return fn()
    finally:
        signal.signal(signal.SIGINT, before)


def test_ctrl_c_swallowed_by_a_callback_still_stops_the_tool_without_a_traceback(capsys, monkeypatch):
    monkeypatch.setattr("sys.unraisablehook", sys.__unraisablehook__)  # Python's own, not pytest's
    status = _with_default_sigint(lambda: run_cli(_ctrl_c_inside_a_callback, [], prog="prog"))
    err = capsys.readouterr().err
    assert status == 130 and "prog: interrupted" in err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_a_ctrl_c_still_pending_when_the_tool_ends_does_not_reach_the_caller(monkeypatch):
    monkeypatch.setattr("sys.unraisablehook", sys.__unraisablehook__)
    monkeypatch.setattr("repro._cli.REDELIVER_CTRL_C_S", 0.5)  # the tool surely ends before the re-press

    def swallow_and_return(argv=None):
        thing = _Thing()
        ref = weakref.ref(thing, lambda r: (_ for _ in ()).throw(KeyboardInterrupt))
        del thing  # the callback runs here (reference count 0), not in a later garbage collection
        return 0 if ref() is None else 1

    def run_then_wait():
        status = run_cli(swallow_and_return, [], prog="prog")
        time.sleep(1.0)  # longer than the re-press delay: a timer left running would interrupt here
        return status

    assert _with_default_sigint(run_then_wait) == 0


def test_without_the_hook_python_swallows_the_ctrl_c(capsys, monkeypatch):
    """The failure the hook exists for: outside run_cli the same Ctrl-C is lost and prints a traceback."""
    monkeypatch.setattr("sys.unraisablehook", sys.__unraisablehook__)
    assert _with_default_sigint(_ctrl_c_inside_a_callback) == 0
    assert "Exception ignored" in capsys.readouterr().err


def test_bugs_propagate():
    with pytest.raises(RuntimeError):
        run_cli(_raiser(RuntimeError("bug")), [], prog="prog")


def test_status_passes_through():
    assert run_cli(lambda argv=None: None, []) == 0
    assert run_cli(lambda argv=None: 1, []) == 1


# ------------------------------------------------------------------------------------------------
# the defocus-repro console script and the flags shared by every tool
# ------------------------------------------------------------------------------------------------
import importlib.util  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

from repro._cli import COMMANDS, console_main, version_string  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
AVAILABLE = [name for name in COMMANDS if importlib.util.find_spec(f"repro.{name}") is not None]
#: Commands that reuse cached results, so they have --force.
CACHED = ("figures", "render", "evaluate", "estimate", "magnify")


def test_console_script_is_declared():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["scripts"] == {"defocus-repro": "repro._cli:console_main"}
    assert set(COMMANDS) == {"figures", "render", "evaluate", "estimate", "magnify", "report", "bench", "sweep"}
    for name in ("figures", "render", "evaluate", "estimate", "magnify", "report", "bench"):
        assert name in AVAILABLE


def _help(name, capsys) -> str:
    with pytest.raises(SystemExit) as e:
        console_main([name, "--help"])
    assert e.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("name", AVAILABLE)
def test_every_command_has_version_and_the_shared_flag_names(name, capsys):
    with pytest.raises(SystemExit) as e:
        console_main([name, "--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == version_string()
    text = _help(name, capsys)
    assert "--version" in text
    assert "--no-cache" not in text  # one documented name: --force
    if "--quiet" in text:
        assert "-q, --quiet" in text
    if name in CACHED:
        assert "--force" in text


def test_help_texts_list_registry_names(capsys, monkeypatch):
    from experiments.registry import FIGURES
    from method import BLUR_ESTIMATORS, MAGNIFICATION_KERNELS, PRESETS
    from method.magnify.magnification import MAP_FLOOR_MODES
    from scenes import SCENES

    checks = {"figures": [*FIGURES, *PRESETS], "render": list(SCENES), "evaluate": [*BLUR_ESTIMATORS, *PRESETS],
              "estimate": [*BLUR_ESTIMATORS, *PRESETS],
              "magnify": [*BLUR_ESTIMATORS, *PRESETS, *MAGNIFICATION_KERNELS, *MAP_FLOOR_MODES]}
    for name, needles in checks.items():
        text = " ".join(_help(name, capsys).split())
        for needle in needles:
            assert needle in text, (name, needle)


def test_unknown_or_missing_command_is_one_line_exit_2(capsys, monkeypatch):
    assert console_main(["nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "command='nope' is invalid (unknown command)" in err[0] and "'figures'" in err[0]
    assert console_main([]) == 2
    assert "commands:" in capsys.readouterr().err
    monkeypatch.setitem(COMMANDS, "nosuchtool", "a command whose module is not installed")
    assert console_main(["nosuchtool"]) == 2
    assert "not available" in capsys.readouterr().err
    assert console_main(["--version"]) == 0 and capsys.readouterr().out.strip() == version_string()
    assert console_main(["--help"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in COMMANDS)


def test_errors_through_the_console_script_name(capsys):
    assert console_main(["figures", "nofig"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("defocus-repro figures: error:") and "nofig" in err[0]
    assert console_main(["bench", "--sizes", "8"]) == 2  # bench goes through the same runner
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sizes" in err[0]


def test_installed_script_and_python_m_both_work():
    script = Path(sys.executable).parent / "defocus-repro"
    if not script.exists():
        pytest.skip("package not installed into this interpreter's environment (make test installs it)")
    got = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=120)
    assert got.returncode == 0 and got.stdout.strip() == version_string()
    got = subprocess.run([str(script), "magnify", "nope.jpg", "-q"], capture_output=True, text=True, timeout=120)
    assert got.returncode == 2 and got.stderr.startswith("defocus-repro magnify: error:")
    for cmd in ([sys.executable, "-m", "repro.estimate", "--version"], [sys.executable, "-m", "repro", "--version"]):
        got = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
        assert got.returncode == 0 and got.stdout.strip() == version_string(), cmd
