"""``python -m repro.evaluate --procedural``: serial and Dask tables equal, a killed worker and a Ctrl-C lose no
finished scene, fresh seeds are recorded and rerun, bad input is one line with nothing written.

Every run uses a private cache (renders at the small preset, 16 spp, the paper preset, f/2 only, of seeds
whose scenes have few objects: a few seconds per scene cold); every process a test starts is stopped by
the test.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PLAN = ["--procedural", "3", "--split", "test", "--scene-seed-start", "100073", "--fnumber", "2", "--preset", "paper", "--spp", "16",
        "--scene-preset", "small"]
TIMEOUT_S = 300.0


@pytest.fixture(scope="module")
def cache_env(tmp_path_factory):
    """A private render cache for this module (in this process and in the subprocesses it starts)."""
    from scenes.backend import cache_root

    cache = tmp_path_factory.mktemp("procedural-cache")
    probes = cache_root() / "variant-probes.json"  # the Mitsuba variant probe is not under test: reuse it
    if probes.is_file():
        shutil.copy(probes, cache / probes.name)
    mp = pytest.MonkeyPatch()
    mp.setenv("DEFOCUS_CACHE_DIR", str(cache))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.setdefault("DRJIT_CACHE_DIR", str(ROOT / ".cache" / "drjit"))
    yield env
    mp.undo()


def _evaluate(args, capsys=None):
    from repro._cli import run_cli
    from repro.evaluate import PROG, main

    return run_cli(main, list(args), prog=PROG)


def _table(folder):
    from experiments.results_table import read_results

    return read_results(Path(folder) / "results.parquet")[0]


def _only(root: Path) -> Path:
    (folder,) = [p for p in root.iterdir() if p.is_dir()]
    return folder


def _cells(folder=None) -> dict:
    """``{store folder name: manifest mtime}`` of PLAN's scenes the case store holds (``$DEFOCUS_CACHE_DIR``)."""
    from experiments.cases import stored_case
    from experiments.procedural_eval import plan_evaluation
    from experiments.units import PROCEDURAL

    plan = plan_evaluation(3, split="test", start=100073, presets=["paper"], f_numbers=[2.0], scene_size="small",
                           spp=16)
    store = Path(os.environ["DEFOCUS_CACHE_DIR"]) / "figures"
    out = {}
    for case in PROCEDURAL.cases(plan):
        stored = stored_case(PROCEDURAL, plan, case, cache_dir=store)
        if stored is not None:
            out[stored.name] = (stored / "manifest.json").stat().st_mtime_ns
    return out


def _popen(args, env):
    return subprocess.Popen([sys.executable, "-m", "repro.evaluate", *args], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _stop(proc):
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        proc.communicate(timeout=10)
    except (subprocess.TimeoutExpired, ValueError):
        pass


def _cluster(folder: Path, env: dict) -> tuple[str, list]:
    """``dask scheduler`` + two single-threaded ``dask worker`` processes on 127.0.0.1: (address, processes)."""
    folder.mkdir(parents=True, exist_ok=True)
    sched_file = folder / "scheduler.json"
    quiet = dict(cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file)], **quiet)]
    deadline = time.monotonic() + 120
    while not sched_file.exists():
        assert time.monotonic() < deadline and procs[0].poll() is None, "dask scheduler did not start"
        time.sleep(0.1)
    for i in range(2):
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(sched_file),
             "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard", "--name", f"w{i}",
             "--local-directory", str(folder / f"w{i}")], **quiet))
    return json.loads(sched_file.read_text())["address"], procs


def _wait(predicate, proc, what):
    deadline = time.monotonic() + TIMEOUT_S
    while not predicate():
        assert proc.poll() is None, f"the evaluation ended before {what}: {proc.communicate()[1][-2000:]}"
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


def _killed_then_interrupted(env, root: Path, folder_root: Path) -> dict:
    """The plan on a scheduler with two workers (cold renders). After the first scene is stored, the worker
    running another scene is SIGKILLed (the scheduler reruns that scene elsewhere); after the next scene is
    stored, Ctrl-C. Returns what happened."""
    from dask.distributed import Client

    address, procs = _cluster(folder_root, env)
    proc = _popen([*PLAN, "--scheduler", address, "--out", str(root)], env)
    try:
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=180)

            def folder():
                return next((p for p in root.iterdir() if p.is_dir()), None) if root.is_dir() else None

            _wait(lambda: folder() is not None and _cells(folder()), proc, "the first scene")
            before = _cells(folder())

            def busy():
                return [w for w, keys in client.processing().items()
                        if any(str(k).startswith("case-procedural-") for k in keys)]

            _wait(busy, proc, "a running scene")
            worker = busy()[0]
            os.kill(client.run(os.getpid, workers=[worker])[worker], signal.SIGKILL)
            _wait(lambda: len(_cells(folder())) > len(before), proc, "a scene after the kill")
            at_sigint = _cells(folder())
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=120)
    finally:
        _stop(proc)
        for p in reversed(procs):
            _stop(p)
    return {"address": address, "folder": folder(), "before_kill": before, "at_sigint": at_sigint,
            "returncode": proc.returncode, "stderr": stderr}


@pytest.fixture(scope="module")
def runs(cache_env, tmp_path_factory):
    """A Dask run with a killed worker and a Ctrl-C, the same command again in this process (resume), and the
    serial reference (this process, no Dask, renders now cached)."""
    import contextlib
    import io

    tmp = tmp_path_factory.mktemp("runs")
    dask = _killed_then_interrupted(cache_env, tmp / "dask", tmp / "cluster")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        dask["resume_status"] = _evaluate([*PLAN, "--workers", "1", "--out", str(tmp / "dask"), "-q"])
    dask["resume_stderr"] = err.getvalue()
    shared = Path(os.environ["DEFOCUS_CACHE_DIR"])
    own = tmp / "serial-cache"  # a case store of its own (the renders shared): the scenes are scored again
    own.mkdir()
    (own / "renders").symlink_to(shared / "renders", target_is_directory=True)
    for probes in shared.glob("variant-probes.json"):
        shutil.copy(probes, own / probes.name)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DEFOCUS_CACHE_DIR", str(own))
        assert _evaluate([*PLAN, "--workers", "1", "--out", str(tmp / "serial"), "-q"]) == 0
        assert len(_cells()) == 3
    serial = _only(tmp / "serial")
    return {"dask": dask, "serial": (serial, _table(serial))}


@pytest.mark.render
def test_serial_table_summary_and_records(runs):
    from experiments.results_table import column_names, read_results_csv

    folder, rows = runs["serial"]
    assert list(rows[0]) == list(column_names())
    scenes = {"procedural_100073", "procedural_100074", "procedural_100075"}
    assert {r["scene"] for r in rows} == scenes
    assert {r["split"] for r in rows} == {"test"} and {r["evaluation_id"] for r in rows} == {folder.name}
    by = {(r["scene"], r["metric"]): r["value"] for r in rows if r["preset"] in (None, "paper")}
    for s in scenes:
        assert by[(s, "gt_sigma_min")] < 0.35 and by[(s, "gt_sigma_max")] > 2.0  # f/2, 160 px: in focus to > 2 px
        assert by[(s, "sparse_n")] > 50 and 0 < by[(s, "dense_textured_mae")] < 5
    assert read_results_csv(folder / "results.csv") == rows
    summary = json.loads((folder / "summary.json").read_text())
    (mae,) = [g for g in summary["summary"] if g["metric"] == "dense_textured_mae" and g["preset"] == "paper"]
    assert {g["preset"] for g in summary["summary"]} == {"paper", "const_median_gt", "const_floor"}  # baselines too
    assert mae["n_scenes"] == 3 and mae["ci_low"] <= mae["mean"] <= mae["ci_high"]
    run = json.loads((folder / "run.json").read_text())
    assert run["seeds"] == [100073, 100075] and "--scene-seed-start 100073" in run["rerun"]
    timings = json.loads((folder / "timings.json").read_text())
    assert sum(k["scenes"] for k in timings["per_lighting"].values()) == 3


@pytest.mark.render
@pytest.mark.slow
def test_killed_worker_and_ctrl_c_lose_no_finished_scene(runs):
    d = runs["dask"]
    assert d["returncode"] == 130, d["stderr"][-3000:]
    assert f"engine: {d['address']} with 2 worker(s)" in d["stderr"] and "interrupted" in d["stderr"]
    assert 2 <= len(d["at_sigint"]) <= 3
    assert d["resume_status"] == 0
    assert f"resuming: {len(d['at_sigint'])} of 3 scenes read back" in d["resume_stderr"]
    final = _cells(d["folder"])
    assert len(final) == 3
    for stored in (d["before_kill"], d["at_sigint"]):  # stored before the kill / the Ctrl-C: never rewritten
        assert all(final[n] == m for n, m in stored.items())


@pytest.mark.render
@pytest.mark.slow
def test_dask_workers_and_serial_give_the_same_table(runs):
    folder, rows = runs["serial"]
    assert runs["dask"]["folder"].name == folder.name  # the same plan: the same evaluation id
    assert _table(runs["dask"]["folder"]) == rows  # scenes scored on two Dask workers, the rest in this process


@pytest.mark.render
def test_fresh_seeds_are_recorded_and_their_record_reruns_the_table(cache_env, tmp_path, capsys):
    from scenes.library.procedural import SPLITS

    common = ["--procedural", "1", "--fnumber", "2", "--preset", "paper", "--spp", "9", "--workers", "1", "-q"]
    assert _evaluate([*common, "--split", "fresh", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    run = json.loads((_only(tmp_path / "a") / "run.json").read_text())
    start = run["seeds"][0]
    assert start in SPLITS["fresh"] and f"--scene-seed-start {start}" in err and f"--scene-seed-start {start}" in run["rerun"]
    rows = _table(_only(tmp_path / "a"))
    assert {r["split"] for r in rows} == {"fresh"} and {r["seed"] for r in rows} == {start}
    assert _evaluate([*common, "--split", "fresh", "--scene-seed-start", str(start), "--out", str(tmp_path / "b")]) == 0
    assert _table(_only(tmp_path / "b")) == rows


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("args, needle", [
    (["--procedural", "2", "--split", "train"], "unknown split"),
    (["--procedural", "0", "--split", "dev"], "--procedural"),
    (["--procedural", "-2", "--split", "dev"], "--procedural"),
    (["--procedural", "5", "--split", "dev", "--scene-seed-start", "99998"], "overlaps the test split"),
    (["--procedural", "2", "--split", "test", "--scene-seed-start", "5"], "overlaps the dev split"),
    (["--procedural", "2"], "needs --split"),
    (["--procedural", "2", "--split", "dev", "--noise", "iso9"], "unknown noise level"),
    (["--procedural", "2", "--split", "dev", "--preset", "nope"], "unknown preset"),
    (["--procedural", "2", "--split", "dev", "--scenes", "planes"], "does not take --scenes"),
    (["--procedural", "2", "--split", "dev", "--scheduler", "tcp://127.0.0.1:{port}"], "unreachable"),
    (["--procedural", "2", "--split", "dev", "--scheduler", "localhost"], "tcp://HOST:PORT"),
    (["--procedural", "2", "--split", "dev", "--workers", "0"], "--workers"),
    (["--split", "dev"], "invalid without --procedural"),
])
def test_bad_input_is_one_line_exit_2_and_nothing_written(args, needle, tmp_path, capsys, monkeypatch):
    from repro import _runner

    monkeypatch.setattr(_runner, "start_client", lambda **k: pytest.fail("an engine was started"))
    args = [a.format(port=_free_port()) for a in args]
    out = tmp_path / "out"
    assert _evaluate([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()
