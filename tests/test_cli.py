"""repro._cli.run_cli: user and machine errors become one stderr line; bugs propagate with their traceback."""

import gc
import signal
import sys
import time
import weakref

import pytest

from repro._cli import ArgumentParser, CLIError, run_cli, user_input


def _raiser(exc):
    def main(argv=None):
        raise exc
    return main


@pytest.mark.parametrize("exc, needle", [
    (CLIError("x=3 is invalid; allowed: > 4"), "x=3 is invalid"),
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
    with pytest.raises(ValueError, match="operands could not be broadcast"):  # a plain ValueError is a bug
        run_cli(_raiser(ValueError("operands could not be broadcast together")), [], prog="prog")


def _validating(argv=None):
    """A tool whose validator (an API function raising ValueError) is wrapped in user_input."""
    args = ArgumentParser(prog="prog").parse_args(argv)
    with user_input():
        int("x")  # the API's ValueError on what the user gave
    return 0 if args else 1


def test_user_input_turns_the_apis_value_error_into_a_user_error(capsys):
    assert run_cli(_validating, [], prog="prog") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["prog: error: invalid literal for int() with base 10: 'x'"]
    with pytest.raises(CLIError, match="^--n bad$") as info:
        with user_input("--n"):
            raise ValueError("bad")
    assert isinstance(info.value.__cause__, ValueError)  # chained: --debug shows where it was raised

    @user_input()
    def check(x):
        if x < 0:
            raise ValueError(f"x={x} is invalid")
        return x

    assert check(1) == 1
    with pytest.raises(CLIError, match="x=-1"):
        check(-1)
    with pytest.raises(TypeError):  # only ValueError is a user error
        with user_input():
            raise TypeError("a bug")


@pytest.mark.parametrize("flag", ["--debug", "--deb"])
def test_debug_shows_the_traceback_of_a_user_error(capsys, flag):
    assert run_cli(_validating, [flag], prog="prog") == 2
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and 'int("x")' in err  # where the API raised
    assert err.strip().splitlines()[-1] == "prog: error: invalid literal for int() with base 10: 'x'"
    assert run_cli(_raiser(CLIError("bad")), ["--debug"], prog="prog") == 2  # also before any parser ran
    assert "Traceback" in capsys.readouterr().err
    assert run_cli(_raiser(CLIError("bad")), ["--", "--debug"], prog="prog") == 2  # an argument, not the flag
    assert "Traceback" not in capsys.readouterr().err


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
CACHED = ("figures", "render", "evaluate", "estimate", "magnify", "sweep", "dataset")


def test_console_script_is_declared():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["scripts"] == {"defocus-repro": "repro._cli:console_main"}
    assert set(COMMANDS) == {"figures", "render", "evaluate", "compare", "estimate", "magnify", "report", "bench",
                             "sweep", "dataset", "warmup"}
    for name in ("figures", "render", "evaluate", "estimate", "magnify", "report", "bench", "dataset"):
        assert name in AVAILABLE


def test_every_tool_is_a_sub_command():
    """Every ``repro/X.py`` with a ``main`` is ``defocus-repro X`` (private ``_X.py`` helpers aside)."""
    import ast

    tools = sorted(p.stem for p in (ROOT / "repro").glob("*.py") if not p.name.startswith("_")
                   and any(isinstance(n, ast.FunctionDef) and n.name == "main"
                           for n in ast.parse(p.read_text(encoding="utf-8")).body))
    assert tools == sorted(COMMANDS)


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
    assert "--version" in text and "--debug" in text
    assert "--no-cache" not in text  # one documented name: --force
    assert "--scene-preset" not in text  # one name for the render size: --scene-size
    if "--quiet" in text:
        assert "-q, --quiet" in text
    if name in CACHED:
        assert "--force" in text


@pytest.mark.parametrize("name", AVAILABLE)
def test_every_tool_has_quiet(name, capsys):
    assert "-q, --quiet" in _help(name, capsys)


def test_preset_means_a_method_preset_with_its_default_in_the_help(capsys):
    """``--preset`` names ``method.PRESETS`` only (the render size is ``--scene-size``), its help states the
    tool's default."""
    import re

    from method import PRESETS

    for name in ("estimate", "magnify", "sweep", "evaluate", "bench"):
        text = " ".join(_help(name, capsys).split())
        m = re.search(r"--preset NAME( \[NAME ...\])? method parameter sets? \(method.PRESETS\).*?Default: (\w+)", text)
        assert m and m.group(2) in PRESETS, (name, text)
    text = " ".join(_help("render", capsys).split())
    assert "--preset" not in text and "--scene-size {small,full}" in text


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


def test_old_flag_names_still_work_hidden():
    """``--scene-size`` is the render size everywhere; the earlier names parse the same and are not shown."""
    from repro import dataset, render, sweep

    for argv in (["planes", "--scene-size", "full"], ["planes", "--preset", "full"], ["planes", "--scene-preset", "full"]):
        assert render._parser().parse_args(argv).scene_size == "full"
    assert render._parser().parse_args(["planes"]).scene_size is None  # the size follows --resolution, else small
    with pytest.raises(CLIError, match="not allowed with"):
        render._parser().parse_args(["planes", "--scene-size", "full", "--resolution", "64x48"])
    for module, base in ((sweep, ["--out", "x"]), (dataset, ["export", "--out", "x"])):
        assert module._parser().parse_args(base).scene_size == "small"
        for flag in ("--scene-size", "--scene-preset"):
            assert module._parser().parse_args([*base, flag, "full"]).scene_size == "full"
        with pytest.raises(CLIError, match="invalid choice"):
            module._parser().parse_args([*base, "--scene-size", "huge"])
    assert sweep._parser().parse_args(["--out", "x"]).quiet is False
    assert sweep._parser().parse_args(["--out", "x", "--no-progress"]).quiet is True
    assert sweep._parser().parse_args(["--out", "x", "-q"]).quiet is True
    assert sweep._parser().parse_args(["--out", "x"]).preset == ["paper"]


def test_bench_presets_is_a_hidden_alias_of_preset(capsys):
    """``repro.bench --preset`` like every tool; ``--presets`` (its earlier name) parses the same, unshown."""
    from experiments.bench import BENCH_PRESETS
    from repro import bench

    parse = bench._parser().parse_args
    assert parse([]).preset == list(BENCH_PRESETS)
    assert parse(["--preset", "robust", "zhuo_sim"]).preset == ["robust", "zhuo_sim"]
    assert parse(["--presets", "robust", "zhuo_sim"]).preset == ["robust", "zhuo_sim"]
    text = _help("bench", capsys)
    assert "--preset NAME [NAME ...]" in text and "--presets" not in text


def test_single_output_files_are_o_output_and_folders_out(capsys):
    """``-o/--output FILE`` names a single output file, ``--out DIR`` a folder; ``repro.render --out FILE``
    (its earlier name) parses the same and is not shown."""
    import re

    from repro import render

    parse = render._parser().parse_args
    for flag in ("-o", "--output", "--out"):
        assert parse(["planes", flag, "x.exr"]).output == "x.exr"
    assert parse(["planes"]).output is None
    for name in ("render", "estimate", "magnify"):
        text = _help(name, capsys)
        assert re.search(r"-o (\w+), --output \1", text) and not re.search(r"--out\b(?!put)", text), name
    for name in ("figures", "evaluate", "report", "bench", "sweep", "dataset", "compare"):
        text = _help(name, capsys)
        assert "--out DIR" in text and "--output" not in text, name


def test_workers_has_one_default_in_every_tool(capsys):
    """Every tool that runs cases in parallel takes --workers N (alias --jobs), default one per core, said in --help."""
    tools = [name for name in AVAILABLE if "--workers" in _help(name, capsys)]
    assert sorted(tools) == ["bench", "compare", "evaluate", "figures", "sweep"]
    for name in tools:
        text = " ".join(_help(name, capsys).split())
        assert "--workers N, --jobs N" in text and "(default: one per core;" in text, name
