"""Exploratory runs never touch the committed report: in a temporary copy of the repository, a quick figure
run and ``repro.report`` leave ``git status`` clean, while the same quick results sent into
``report/figures`` on purpose are refused by the committed report (the rule that tells quick from full,
both ways)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.numba_cache import seed_kernels

ROOT = Path(__file__).resolve().parents[1]


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout


@pytest.fixture
def repo_copy(tmp_path) -> Path:
    """The tracked files of this checkout (as they are in the working tree) committed into a new repository."""
    repo = tmp_path / "repo"
    for name in _git(ROOT, "ls-files", "-z").split("\0"):
        src = ROOT / name
        if name and src.is_file():
            (repo / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, repo / name)
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "copy")
    # numba's compiled kernels of this checkout (git-ignored): the copy loads them instead of compiling
    seed_kernels(os.environ.get("NUMBA_CACHE_DIR"), dest_root=repo)
    return repo


def _run(repo: Path, module: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(repo)}
    env.setdefault("DRJIT_CACHE_DIR", str(ROOT / ".cache" / "drjit"))  # renders: the shared $DEFOCUS_CACHE_DIR
    return subprocess.run([sys.executable, "-m", module, *args], cwd=repo, env=env, capture_output=True, text=True,
                          timeout=900)


def _status(repo: Path) -> list[str]:
    return _git(repo, "status", "--porcelain").splitlines()


@pytest.mark.slow
@pytest.mark.render
def test_a_quick_run_and_the_report_leave_git_status_clean(repo_copy):
    repo = repo_copy
    # the committed report as this code writes it from the committed results (its freshness is not tested here)
    assert _run(repo, "repro.report", "-q").returncode == 0
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qam", "report", "--allow-empty")
    readme = (repo / "README.md").read_bytes()

    proc = _run(repo, "repro.figures", "fig10", "--quick", "--workers", "1", "-q")
    assert proc.returncode == 0, proc.stderr[-3000:]
    quick = repo / "report" / "quick" / "figures"
    assert (quick / "fig10.png").is_file() and (quick / "results.csv").is_file()
    assert "fig10-quick-" in (quick / "results.csv").read_text()
    assert _status(repo) == []
    proc = _run(repo, "repro.report", "-q")
    assert proc.returncode == 0, proc.stderr
    assert _status(repo) == []
    proc = _run(repo, "repro.report", "--figures", "report/quick/figures", "-q")
    assert proc.returncode == 0, proc.stderr
    assert "(mode: quick)" in (repo / "report" / "quick" / "README.md").read_text()
    assert _status(repo) == [] and (repo / "README.md").read_bytes() == readme

    # the other side: the quick results sent into the committed folder on purpose change it, and the
    # committed report refuses them (one line, exit 2) instead of turning them into README verdicts
    proc = _run(repo, "repro.figures", "fig10", "--quick", "--workers", "1", "-q", "--out", "report/figures")
    assert proc.returncode == 0, proc.stderr[-3000:]
    changed = {line[3:] for line in _status(repo)}
    assert {"report/figures/fig10.png", "report/figures/results.csv"} <= changed, changed
    proc = _run(repo, "repro.report", "-q")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "fig10 (quick)" in proc.stderr
    assert {line[3:] for line in _status(repo)} == changed and (repo / "README.md").read_bytes() == readme


def test_the_exploratory_defaults_are_git_ignored_and_the_committed_folders_are_not():
    import repro._evaluate_procedural as procedural
    import repro.evaluate as evaluate
    import repro.figures as figures
    from repro._report_paths import EVALUATIONS

    def ignored(path: Path) -> bool:
        return subprocess.run(["git", "check-ignore", "-q", "--no-index", path.as_posix()], cwd=ROOT).returncode == 0

    assert ignored(figures.QUICK_OUT / "results.csv") and ignored(evaluate.DEFAULT_OUT / "evaluate.csv")
    assert ignored(procedural.DEFAULT_ROOT / "test-100000-n8-small-0000abcd" / "results.csv")
    assert not ignored(figures.DEFAULT_OUT / "results.csv")
    assert not ignored(EVALUATIONS / "test-100000-n8-small-0000abcd" / "results.csv")
