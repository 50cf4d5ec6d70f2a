"""``python -m repro.warmup``: compiles the photo tools' numba kernels into numba's cache."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from repro._cli import console_main

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_warmup_populates_an_empty_numba_cache(tmp_path):
    """One preset into an empty NUMBA_CACHE_DIR: index (.nbi) and code (.nbc) files of the method's
    kernels appear, nothing is printed on stdout, and the map cache of the run is not the user's."""
    numba_dir, user_cache = tmp_path / "numba", tmp_path / "user-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(numba_dir), "DEFOCUS_CACHE_DIR": str(user_cache),
           "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "repro.warmup", "--preset", "paper", "-q"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout == ""
    index = list(numba_dir.rglob("*.nbi"))
    assert {p.parent.name.split("_")[0] for p in index} >= {"edges", "blur", "propagation"}
    assert list(numba_dir.rglob("*.nbc"))
    assert not (user_cache / "maps").exists()


def test_warmup_bad_preset_is_one_line(capsys):
    assert console_main(["warmup", "--preset", "nope", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope" in err[0]
