"""A bug is not a user error: a ``ValueError`` raised inside the method shows its traceback (exit status
1 from ``python -m``), while a bad flag, file or name stays one line and exit status 2; ``--debug`` gives
the traceback of a user error too.

The bug is a deliberate one: a pipeline stage monkeypatched to raise the ``ValueError`` a numpy
broadcasting mistake raises.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from repro._cli import run_cli
from repro.photo_io import write_photo
from tests.photo_cli import textured_photo

ROOT = Path(__file__).resolve().parents[1]
BUG = "operands could not be broadcast together with shapes (96,128) (3,)"


def _broken_stage(*args, **kwargs):
    raise ValueError(BUG)


@pytest.fixture
def photo(tmp_path, monkeypatch):
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path / "cache"))  # no cached map skips the pipeline
    return write_photo(tmp_path / "photo.png", textured_photo())


@pytest.mark.parametrize("tool, stage, extra", [
    ("estimate", "method.pipeline.propagate_blur_measures", []),
    ("magnify", "method.pipeline.propagate_blur_measures", ["--factor", "2"]),
    ("magnify", "method.magnify.upsampling.magnify_defocus_tiled", ["--map", "MAP"]),
])
def test_a_value_error_inside_the_method_is_a_bug(tmp_path, photo, monkeypatch, capsys, tool, stage, extra):
    import importlib

    import numpy as np

    module = importlib.import_module(f"repro.{tool}")
    np.save(tmp_path / "map.npy", np.ones((96, 128)))
    extra = [str(tmp_path / "map.npy") if a == "MAP" else a for a in extra]
    out = tmp_path / ("out.exr" if tool == "estimate" else "out.png")
    owner, name = stage.rsplit(".", 1)
    monkeypatch.setattr(importlib.import_module(owner), name, _broken_stage)
    with pytest.raises(ValueError, match="could not be broadcast"):  # propagates: Python prints the traceback
        run_cli(module.main, [str(photo), "-o", str(out), "-q", *extra], prog=module.PROG)
    assert "error:" not in capsys.readouterr().err and not out.exists()
    # the same run with a bad flag is a user error: one line, exit status 2
    assert run_cli(module.main, [str(photo), "-o", str(out), "--preset", "nope", *extra], prog=module.PROG) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{module.PROG}: error: ") and "'nope'" in err[0]


_SCRIPT = """
import sys
import method.pipeline
def broken(*args, **kwargs):
    raise ValueError({bug!r})
if sys.argv[1] == "bug":
    method.pipeline.propagate_blur_measures = broken
from repro._cli import run_cli
from repro.estimate import PROG, main
sys.exit(run_cli(main, sys.argv[2:], prog=PROG))
"""


def _run(tmp_path, mode, *args):
    env = {"DEFOCUS_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin",
           "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-c", _SCRIPT.format(bug=BUG), mode, *map(str, args)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env)


def test_as_a_process_a_bug_has_a_traceback_and_a_user_error_one_line(tmp_path, photo):
    bug = _run(tmp_path, "bug", photo, "-o", tmp_path / "m.exr", "-q")
    assert bug.returncode == 1, bug.stderr
    assert "Traceback (most recent call last)" in bug.stderr and f"ValueError: {BUG}" in bug.stderr
    assert "in broken" in bug.stderr and "error:" not in bug.stderr and not (tmp_path / "m.exr").exists()

    user = _run(tmp_path, "ok", photo, "-o", tmp_path / "m.exr", "--alpha", "-1")
    assert user.returncode == 2 and "Traceback" not in user.stderr
    assert user.stderr.strip().splitlines() == ["python -m repro.estimate: error: --alpha -1 is invalid; "
                                                "allowed: a finite number > 0"]

    debug = _run(tmp_path, "ok", photo, "-o", tmp_path / "m.exr", "--preset", "nope", "--debug")
    assert debug.returncode == 2
    assert "Traceback (most recent call last)" in debug.stderr and "registry.py" in debug.stderr  # where it was raised
    last = debug.stderr.strip().splitlines()[-1]
    assert last.startswith("python -m repro.estimate: error: ") and "'nope'" in last
    assert not (tmp_path / "m.exr").exists()
