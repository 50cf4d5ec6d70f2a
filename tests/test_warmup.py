"""``python -m repro.warmup``: compiles the photo tools' numba kernels into numba's cache."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from repro._cli import console_main
from tests.numba_cache import kernel_dir, seed_kernels

ROOT = Path(__file__).resolve().parents[1]


#: The source file whose kernels the seeded cache lacks (two small kernels the paper preset runs).
LEFT_OUT = ROOT / "method" / "edges" / "elder_zucker.py"


@pytest.mark.slow
def test_warmup_compiles_what_the_cache_lacks_and_loads_the_rest(tmp_path):
    """One preset into a NUMBA_CACHE_DIR holding the set-up's kernels of every source but one: that source's
    index (.nbi) and code (.nbc) files appear, no seeded kernel is compiled again (its code file is left as
    it was), nothing is printed on stdout, and the map cache of the run is not the user's."""
    numba_dir, user_cache = tmp_path / "numba", tmp_path / "user-cache"
    seeded = seed_kernels(numba_dir, skip={LEFT_OUT})  # the set-up's kernels (make setup)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(numba_dir), "DEFOCUS_CACHE_DIR": str(user_cache),
           "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "repro.warmup", "--preset", "paper", "-q"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout == ""
    filled = kernel_dir(LEFT_OUT, numba_dir)
    assert list(filled.glob(f"{LEFT_OUT.stem}.*.nbi")) and list(filled.glob(f"{LEFT_OUT.stem}.*.nbc"))
    recompiled = [p.name for p, (mtime, data) in seeded.items()
                  if p.stat().st_mtime_ns != mtime or p.read_bytes() != data]
    assert recompiled == [], recompiled
    assert not (user_cache / "maps").exists()


def test_warmup_bad_preset_is_one_line(capsys):
    assert console_main(["warmup", "--preset", "nope", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope" in err[0]
