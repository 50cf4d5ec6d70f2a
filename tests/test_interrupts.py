"""Interrupted work: a killed render leaves nothing half-written and is rebuilt; Ctrl-C on
``repro.figures`` keeps finished figures, and the next run resumes from the cache."""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.render

#: Longest wait for a subprocess to reach the state the test interrupts, s (generous: loaded CI).
WAIT_S = 300.0
#: Seconds to wait for the tool to report a Ctrl-C before pressing it again.
RESEND_S = 12.0


def _env(cache):
    return {**os.environ, "DEFOCUS_CACHE_DIR": str(cache)}


def _wait_for(predicate, proc):
    deadline = time.monotonic() + WAIT_S
    while not predicate():
        if proc.poll() is not None:
            return False
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("subprocess never reached the state to interrupt")
        time.sleep(0.05)
    return True


def test_killed_render_is_rebuilt_and_out_never_half_written(tmp_path):
    from scenes import load_render

    cache, out = tmp_path / "cache", tmp_path / "render.exr"
    cmd = [sys.executable, "-m", "repro.render", "planes", "--preset", "small", "--spp", "512",
           "--out", str(out), "--quiet"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=_env(cache), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    renders = cache / "renders"
    # Kill it while its cache entry is being built (a temporary folder exists).
    building = _wait_for(lambda: renders.is_dir() and any(p.name.endswith(".tmp") for p in renders.iterdir()),
                         proc)
    proc.kill()
    proc.communicate()
    assert building, "the render finished before it could be killed; raise --spp"
    assert not out.exists(), "the output appeared although the render was killed mid-way"
    again = subprocess.run(cmd, cwd=ROOT, env=_env(cache), capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    r = load_render(out)
    assert r.rgb.shape == (120, 160, 3) and np.isfinite(r.rgb).all() and r.metadata["spp"] == 512
    assert not list(tmp_path.glob(".render.exr*")), "temporary output files left behind"


def _store_sharing_renders(folder: Path) -> dict:
    """The environment of a subprocess with a case store of its own in ``folder`` whose renders, Mitsuba
    variant probes and Dr.Jit kernels are the session's (content-keyed, file-locked): the figures are computed
    afresh, the renders are read (or made once for every test that needs them)."""
    from scenes.backend import cache_root
    from tests.test_sweep import _own_store

    shared = cache_root()
    env = _own_store({**os.environ, "DEFOCUS_CACHE_DIR": str(shared)}, folder)
    env.setdefault("DRJIT_CACHE_DIR", str(shared / "drjit"))
    return env


def _copy_cases(data, env) -> int:
    """Copy the finished cases of ``data`` (a :class:`experiments.figure_data.FigureData` computed through
    this session's case store) into the case store of ``env``; return how many were copied."""
    import shutil

    from experiments.cache_keys import CACHE_SUBDIR
    from experiments.cases import stored_case

    dest = Path(env["DEFOCUS_CACHE_DIR"]) / CACHE_SUBDIR
    n = 0
    for case in data.outputs:
        folder = stored_case(data.figure, data.config, case)
        if folder is not None:
            shutil.copytree(folder, dest / folder.name)  # the store's folder of an entry: its key's hash
            n += 1
    return n


def test_figures_ctrl_c_then_resume_from_cache(tmp_path, quick_figure):
    out = tmp_path / "figures"
    env = _store_sharing_renders(tmp_path / "cache")
    # fig10's quick cases are the session's (computed once for every test that reads them), copied into
    # this run's store: the first run writes fig10 from them, then computes the photos figure
    assert _copy_cases(quick_figure("fig10"), env) == 3
    # The photos figure's paper map of coffee (seconds; --preset paper: one map, magnified by two renderers)
    # is still being computed when the interrupt arrives, right after fig10's files are written.
    cmd = [sys.executable, "-m", "repro.figures", "fig10", "photos", "--quick", "--preset", "paper", "--workers", "1",
           "--out", str(out)]
    # A shell starts the command with SIGINT at its default; in a full test session an earlier test's
    # library can leave SIGINT ignored in this process, which a child would inherit (seen in CI-like runs).
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    chunks = []  # stderr as it arrives (tqdm writes without newlines), read by a thread
    reader = threading.Thread(target=lambda: chunks.extend(iter(lambda: os.read(proc.stderr.fileno(), 4096), b"")),
                              daemon=True)
    reader.start()
    finished_first = _wait_for(lambda: (out / "fig10.metrics.json").exists(), proc)
    # Press Ctrl-C, and again only if the tool has not said it was interrupted RESEND_S later (a SIGINT that
    # lands inside a Dr.Jit kernel launch can be consumed), as a user would; never while it is already
    # shutting down (a second Ctrl-C then is a forced kill, exit -2).
    # After each Ctrl-C, wait up to RESEND_S for the tool to say so (a signal held until a long
    # kernel returns is answered late; a second one sent then lands in the tool's exit: exit -2, seen
    # in CI with a 3-s wait).
    deadline = time.monotonic() + WAIT_S

    def interrupted():
        return b"interrupted" in b"".join(chunks)

    while finished_first and proc.poll() is None and not interrupted() and time.monotonic() < deadline:
        proc.send_signal(signal.SIGINT)
        answer_by = time.monotonic() + RESEND_S
        while proc.poll() is None and not interrupted() and time.monotonic() < answer_by:
            time.sleep(0.1)
    proc.wait(timeout=WAIT_S)
    reader.join(timeout=10)
    err = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 130, f"not interrupted (exit {proc.returncode}): {err[-2000:]}"
    assert "Traceback" not in err
    assert not (out / "photos.metrics.json").exists() or (out / "photos.png").exists()
    assert not [p for p in out.iterdir() if ".tmp" in p.name], "half-written figure files left behind"
    again = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=WAIT_S)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "fig10: cached" in again.stdout
    assert "photos: computed" in again.stdout
    for name in ("photos", "fig10"):
        assert (out / f"{name}.png").stat().st_size > 1000
