"""``python -m repro.sweep``: a tiny grid on real Dask processes (all on 127.0.0.1).

Grid: ``planes`` at the small preset, f/8 and f/4 (two renders), the zero-crossing estimator, α ∈ {0.5, 2}
(four cells). Serial (one worker) is the reference; two LocalCluster workers, an external
``dask scheduler`` + two ``dask worker`` processes, a run whose worker is SIGKILLed mid-cell, and a run
interrupted with Ctrl-C then resumed must all give the same table. Every sweep uses a private cache
(``$DEFOCUS_CACHE_DIR`` under the test's tmp folder); the sweeps that must compute their cells again get a
case store of their own that shares the serial run's renders (made once per module).
Every process a test starts is stopped by the test. The sweeps are marked ``slow`` (``make test`` and CI
run them; ``make test-fast`` skips them).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.render

GRID = ["--scenes", "planes", "--fnumber", "8", "4", "--estimator", "zero_crossing", "--param", "alpha=0.5,2",
        "--scene-preset", "small"]
N_CELLS, N_RENDERS = 4, 2
#: Longest wait for one sweep subprocess, s (generous: a loaded 2-core CI machine).
TIMEOUT_S = 420.0
#: Columns that must not depend on where or how fast a cell ran.
EXPECTED_INPUTS = ["scene", "camera", "f_number", "scene_preset", "seed", "encoding", "method_preset", "estimator",
                   "alpha", "method_variant", "mitsuba_variant"]


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    cache = tmp_path_factory.mktemp("sweep-cache")
    e = {**os.environ, "DEFOCUS_CACHE_DIR": str(cache), "PYTHONUNBUFFERED": "1"}
    # Dr.Jit's compiled-kernel cache is shared with the project (kernels only; no results).
    e.setdefault("DRJIT_CACHE_DIR", str(ROOT / ".cache" / "drjit"))
    return e


def _popen(args, env, **kw):
    # SIGINT at its default, as a shell gives it (pytest runs may inherit it ignored); own session so
    # that everything it starts can be stopped as a group.
    return subprocess.Popen([sys.executable, "-m", *args], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kw)


def _stop_group(proc):
    """Kill whatever is left of the process group a test started (no-op when it ended cleanly)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        proc.communicate(timeout=10)
    except (subprocess.TimeoutExpired, ValueError):
        pass


def _group_alive(pgid) -> list:
    import psutil

    out = []
    for p in psutil.process_iter(["pid"]):
        try:
            if os.getpgid(p.pid) == pgid and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p.pid)
        except (ProcessLookupError, psutil.Error, OSError):
            pass
    return out


def sweep(env, out, *extra, grid=GRID):
    proc = _popen(["repro.sweep", *grid, "--out", str(out), *extra], env)
    try:
        stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        _stop_group(proc)
        pytest.fail(f"sweep did not finish within {TIMEOUT_S:.0f} s")
    _stop_group(proc)
    return proc.returncode, stdout, stderr


def _grid(grid=GRID):
    """The sweep grid of command-line arguments, as ``repro.sweep`` builds it."""
    from repro.sweep import _parser, build_grid, parse_params
    from scenes import SCENES

    a = _parser().parse_args([*grid, "--out", "unused"])
    return build_grid(scenes=a.scenes or list(SCENES), cameras=a.camera, f_numbers=a.fnumber, estimators=a.estimator,
                      presets=a.preset, params=parse_params(a.param), seeds=a.seeds, scene_preset=a.scene_size,
                      encodings=a.encoding, metric=a.metric, variant=a.variant)


def _finished_cells(env, grid=GRID) -> dict:
    """``{store folder name: manifest mtime}`` of the grid's cells the case store of ``env`` holds."""
    from experiments.cases import stored_case
    from experiments.sweep_cells import UNIT, SweepConfig
    from repro.sweep import sweep_cases

    g = _grid(grid)
    store = Path(env["DEFOCUS_CACHE_DIR"]) / "figures"
    out = {}
    for case in sweep_cases(g):
        folder = stored_case(UNIT, SweepConfig(g.variant), case, cache_dir=store)
        if folder is not None:
            out[folder.name] = (folder / "manifest.json").stat().st_mtime_ns
    return out


def _own_store(env, folder: Path) -> dict:
    """``env`` with a case store of its own that shares ``env``'s renders (and Mitsuba variant probes)."""
    shared = Path(env["DEFOCUS_CACHE_DIR"])
    folder.mkdir(parents=True, exist_ok=True)
    (shared / "renders").mkdir(exist_ok=True)
    (folder / "renders").symlink_to(shared / "renders", target_is_directory=True)
    probes = shared / "variant-probes.json"
    if probes.is_file():
        (folder / probes.name).write_bytes(probes.read_bytes())
    return {**env, "DEFOCUS_CACHE_DIR": str(folder)}


def _table(out):
    from repro.sweep import read_table

    return read_table(Path(out) / "results_wide.parquet")


def _ok(rc, stdout, stderr):
    assert rc == 0, f"exit {rc}\n{stderr[-3000:]}"


@pytest.fixture(scope="module")
def serial(env, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    rc, stdout, stderr = sweep(env, out, "--workers", "1")
    _ok(rc, stdout, stderr)
    return out, _table(out), stdout, stderr


@pytest.mark.slow
def test_serial_sweep_table_summary_plot_and_deduplicated_renders(serial, env):
    from defocus_cache import Cache

    out, rows, stdout, stderr = serial
    assert len(rows) == N_CELLS
    assert list(rows[0])[:len(EXPECTED_INPUTS)] == EXPECTED_INPUTS
    assert {(r["f_number"], r["alpha"]) for r in rows} == {(8.0, 0.5), (8.0, 2.0), (4.0, 0.5), (4.0, 2.0)}
    assert {r["estimator"] for r in rows} == {"zero_crossing"} and {r["scene_preset"] for r in rows} == {"small"}
    assert all(r["mitsuba_variant"] in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb") for r in rows)
    for r in rows:  # real metrics, not placeholders
        assert r["sparse_n"] > 50 and 0 < r["dense_textured_mae"] < 5 and 0 < r["sparse_mae"] < 5
    # f/4 is blurrier than f/8: different renders, so different numbers
    by = {(r["f_number"], r["alpha"]): r for r in rows}
    assert by[(8.0, 0.5)]["sparse_mae"] != by[(4.0, 0.5)]["sparse_mae"]
    # one render task per distinct render; the private cache holds exactly those renders, all valid
    assert f"{N_RENDERS} render tasks" in stdout
    renders = Path(env["DEFOCUS_CACHE_DIR"]) / "renders"
    entries = [p for p in renders.iterdir() if p.is_dir() and not p.name.startswith(".")]
    assert len(entries) == N_RENDERS
    for e in entries:
        key = json.loads((e / "manifest.json").read_text())["key"]
        assert Cache(renders).is_valid(key)
    # progress (cells and renders), summary, plot, the long table, every cell in the case store
    n_cases = N_CELLS + N_RENDERS
    assert f"{n_cases}/{n_cases}" in stderr
    assert "paper/zero_crossing alpha=0.5" in stdout and "mean dense_textured_mae" in stdout
    assert (out / "dense_textured_mae.png").stat().st_size > 5000
    from experiments.results_table import column_names, read_results

    long, _ = read_results(out / "results.parquet")
    assert list(long[0]) == list(column_names()) and {r["source"] for r in long} == {"sweep"}
    wide = {(r["f_number"], r["alpha"]): r["dense_textured_mae"] for r in rows}
    assert {(r["aperture"], float(r["variant"].split("alpha=")[1])): r["value"] for r in long
            if r["metric"] == "dense_textured_mae"} == wide  # the wide table is a view of the long one
    assert len(_finished_cells(env)) == N_CELLS
    assert not list(out.rglob("*.tmp*"))


@pytest.mark.slow
def test_two_local_workers_give_the_serial_table(serial, env, tmp_path):
    rc, stdout, stderr = sweep(_own_store(env, tmp_path / "cache"), tmp_path / "par", "--workers", "2")
    _ok(rc, stdout, stderr)
    assert "LocalCluster with 2 worker(s)" in stderr and "dashboard: http" in stderr
    assert _table(tmp_path / "par") == serial[1]


@pytest.mark.slow
def test_same_command_again_reads_every_cell_back(serial, env):
    out = serial[0]
    before = _finished_cells(env)
    rc, stdout, stderr = sweep(env, out, "--workers", "1")
    _ok(rc, stdout, stderr)
    assert f"{N_CELLS} of {N_CELLS} cells read back" in stderr and "engine:" not in stderr
    assert _finished_cells(env) == before and len(before) == N_CELLS
    assert _table(out) == serial[1]


@pytest.mark.slow
def test_changed_key_is_not_read_back(serial, env):
    """A cell is read back only under its own key: another variant asked for or another parameter value is
    computed again; a damaged entry is not a finished cell."""
    from experiments.cases import stored_case
    from experiments.sweep_cells import UNIT, SweepConfig
    from repro.sweep import sweep_cases

    store = Path(env["DEFOCUS_CACHE_DIR"]) / "figures"
    cases = sweep_cases(_grid())
    assert all(stored_case(UNIT, SweepConfig(), c, cache_dir=store) is not None for c in cases)
    assert all(stored_case(UNIT, SweepConfig("scalar_rgb"), c, cache_dir=store) is None for c in cases)
    other = sweep_cases(_grid([*GRID[:-3], "alpha=7", *GRID[-2:]]))
    assert all(stored_case(UNIT, SweepConfig(), c, cache_dir=store) is None for c in other)
    folder = stored_case(UNIT, SweepConfig(), cases[0], cache_dir=store)
    metrics = folder / "metrics.json"
    text = metrics.read_text()
    try:
        metrics.write_text(text[:40])
        assert stored_case(UNIT, SweepConfig(), cases[0], cache_dir=store) is None
    finally:
        metrics.write_text(text)


# --------------------------------------------------------------------------------------------------
# an external cluster: dask scheduler + two dask worker processes


@pytest.fixture(scope="module")
def external_env(serial, env, tmp_path_factory):
    """A case store of the external cluster's own (the serial run's renders shared)."""
    return _own_store(env, tmp_path_factory.mktemp("cluster-cache") / "cache")


@pytest.fixture(scope="module")
def external(external_env, tmp_path_factory):
    env = external_env
    folder = tmp_path_factory.mktemp("cluster")
    sched_file = folder / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        deadline = time.monotonic() + 120
        while not sched_file.exists():
            assert time.monotonic() < deadline and procs[0].poll() is None, "dask scheduler did not start"
            time.sleep(0.1)
        for i in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(sched_file),
                 "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard", "--name", f"w{i}",
                 "--local-directory", str(folder / f"w{i}")],
                cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        address = json.loads(sched_file.read_text())["address"]
        from dask.distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=180)
        yield address
    finally:
        for p in reversed(procs):
            _stop_group(p)


@pytest.mark.slow
def test_external_scheduler_two_workers_one_sigkilled_mid_cell_table_complete(serial, external_env, external,
                                                                               tmp_path):
    """The grid on ``dask scheduler`` + two ``dask worker`` processes; while a cell runs, its worker is
    SIGKILLed: the scheduler reruns the cell elsewhere, the table equals the serial one, every render
    cache entry is still valid."""
    from dask.distributed import Client

    from defocus_cache import Cache

    env = external_env
    out = tmp_path / "killed"
    proc = _popen(["repro.sweep", *GRID, "--out", str(out), "--scheduler", external], env)
    killed = None
    try:
        with Client(external, timeout="30s") as client:
            deadline = time.monotonic() + TIMEOUT_S
            while killed is None and proc.poll() is None and time.monotonic() < deadline:
                busy = [w for w, keys in client.processing().items()
                        if any(str(k).startswith("case-sweep-") for k in keys)]
                if busy:
                    pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
                    os.kill(pid, signal.SIGKILL)
                    killed = (busy[0], pid)
                time.sleep(0.02)
            stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
            client.wait_for_workers(2, timeout=180)  # the nanny restarted it: the next test has two again
    finally:
        _stop_group(proc)
    assert killed is not None, "no cell was ever running on a worker"
    _ok(proc.returncode, stdout, stderr)
    assert f"engine: {external} with 2 worker(s)" in stderr
    assert _table(out) == serial[1]
    renders = Path(env["DEFOCUS_CACHE_DIR"]) / "renders"
    for e in (p for p in renders.iterdir() if p.is_dir() and not p.name.startswith(".")):
        assert Cache(renders).is_valid(json.loads((e / "manifest.json").read_text())["key"])


# --------------------------------------------------------------------------------------------------
# Ctrl-C, then the same command: finished cells are read back


@pytest.mark.slow
def test_ctrl_c_then_resume_reads_finished_cells_back(serial, env, tmp_path):
    from repro.sweep import read_table

    grid = ["--scenes", "planes", "--fnumber", "8", "--estimator", "zero_crossing", "--param", "alpha=0.5,1,2",
            "--scene-preset", "small"]  # three cells, one render (cached by the serial run)
    env = _own_store(env, tmp_path / "cache")  # the serial run's renders, none of its cells
    out = tmp_path / "resume"
    proc = _popen(["repro.sweep", *grid, "--out", str(out), "--workers", "1"], env)
    try:
        deadline = time.monotonic() + TIMEOUT_S
        while proc.poll() is None and not _finished_cells(env, grid):
            assert time.monotonic() < deadline, "no cell finished"
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
        time.sleep(1.0)
        left = _group_alive(proc.pid)
    finally:
        _stop_group(proc)
    assert proc.returncode == 130, f"exit {proc.returncode}: {stderr[-2000:]}"
    assert "interrupted" in stderr
    assert left == [], f"processes left running after Ctrl-C: {left}"
    done = _finished_cells(env, grid)
    assert 1 <= len(done) < 3
    assert not (out / "results.parquet").exists()
    rc, stdout, stderr = sweep(env, out, "--workers", "1", grid=grid)
    _ok(rc, stdout, stderr)
    assert f"resuming: {len(done)} of 3 cells read back" in stderr
    assert {n: m for n, m in _finished_cells(env, grid).items() if n in done} == done
    rows = _table(out)
    assert len(rows) == 3 and sum(t["resumed"] for t in read_table(out / "timings.parquet")) == len(done)
    ref = {(r["f_number"], r["alpha"]): r for r in serial[1]}
    same = [r for r in rows if r["alpha"] in (0.5, 2.0)]  # the cells the serial grid has too
    assert len(same) == 2 and all(r == ref[(r["f_number"], r["alpha"])] for r in same)


# --------------------------------------------------------------------------------------------------
# bad grids: one line, exit 2, nothing started


@pytest.mark.parametrize("args, needle", [
    (["--scenes", "nope"], "unknown scene"),
    (["--scenes", "planes", "--estimator", "nope"], "unknown estimator"),
    (["--scenes", "planes", "--preset", "nope"], "unknown preset"),
    (["--scenes", "planes", "--camera", "nope"], "unknown camera"),
    (["--scenes", "planes", "--param", "nope=1"], "not a DefocusParams field"),
    (["--scenes", "planes", "--param", "alpha=abc"], "alpha='abc' is invalid"),
    (["--scenes", "planes", "--param", "alpha=0.5,-1"], "alpha"),
    (["--scenes", "planes", "--param", "sharpness_bias=maybe"], "true or false"),
    (["--scenes", "planes", "--param", "sigma1_scales=1"], "tuple fields"),
    (["--scenes", "planes", "--param", "estimator=model_fit"], "--estimator"),
    (["--scenes", "planes", "--param", "alpha"], "FIELD=V1,V2"),
    (["--scenes", "planes", "--fnumber", "0"], "--fnumber"),
    (["--scenes", "planes", "--metric", "nope"], "--metric"),
    (["--scenes", "planes", "--scheduler", "localhost"], "tcp://HOST:PORT"),
    (["--scenes", "planes", "--workers", "0"], "--workers"),
])
def test_bad_grid_one_line_exit_2_before_anything_starts(args, needle, tmp_path, monkeypatch, capsys):
    from repro import _runner, sweep as mod
    from repro._cli import run_cli

    monkeypatch.setattr(_runner, "start_client", lambda **k: pytest.fail("an engine was started for a bad grid"))
    out = tmp_path / "out"
    rc = run_cli(mod.main, [*args, "--out", str(out)], prog=mod.PROG)
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and needle in err, err
    assert not out.exists()


def test_bad_grid_from_the_command_line(env, tmp_path):
    out = tmp_path / "out"
    rc, stdout, stderr = sweep(env, out, grid=["--scenes", "planes", "--estimator", "nope"])
    assert rc == 2 and stderr.strip().count("\n") == 0 and "unknown estimator" in stderr, stderr
    assert not out.exists()


def test_param_values_take_the_field_types():
    from repro.sweep import parse_params

    got = dict(parse_params(["alpha=0.1,1", "fit_max_scale=none,2", "propagation_downsample=auto,2",
                             "sharpness_bias=true,off", "fit_min_samples=3,5", "map_floor=clamp,subtract"]))
    assert got["alpha"] == [0.1, 1.0] and all(isinstance(v, float) for v in got["alpha"])
    assert got["fit_max_scale"] == [None, 2.0]
    assert got["propagation_downsample"] == ["auto", 2]
    assert got["sharpness_bias"] == [True, False]
    assert got["fit_min_samples"] == [3, 5] and all(type(v) is int for v in got["fit_min_samples"])
    assert got["map_floor"] == ["clamp", "subtract"]
    with pytest.raises(ValueError, match="integer"):
        parse_params(["fit_min_samples=3.5"])


def test_grid_enumerates_the_product_with_one_render_per_distinct_render():
    from repro.sweep import build_grid

    g = build_grid(scenes=["planes", "portrait"], f_numbers=[8, 4], estimators=["model_fit", "zero_crossing"],
                   presets=["paper", "robust"], params=[("alpha", [0.5, 1.0])], seeds=[0, 1])
    assert len(g.cells) == 2 * 2 * 2 * 2 * 2 * 2 * 1 and len(g.renders) == 2 * 2 * 2
    assert len({c.variant_label for c in g.cells}) == 8
    # the preset's own estimator when --estimator is not given
    g2 = build_grid(scenes=["planes"], f_numbers=[8], presets=["paper", "robust"])
    from method import PRESETS

    assert [c.estimator for c in g2.cells] == [PRESETS["paper"].estimator, PRESETS["robust"].estimator]


def test_summary_and_plot_from_rows(tmp_path):
    from repro.sweep import format_summary, metric_unit, plot_metric, summary

    rows = [{"method_variant": "paper/model_fit", "scene": "planes", "dense_textured_mae": 1.0},
            {"method_variant": "paper/model_fit", "scene": "portrait", "dense_textured_mae": 3.0},
            {"method_variant": "robust/model_fit_checked", "scene": "planes", "dense_textured_mae": None},
            {"method_variant": "robust/model_fit_checked", "scene": "portrait", "dense_textured_mae": 0.5}]
    s = {r["method_variant"]: r for r in summary(rows, "dense_textured_mae")}
    assert s["paper/model_fit"] == {"method_variant": "paper/model_fit", "cells": 2, "n": 2, "mean": 2.0,
                                    "median": 2.0, "min": 1.0, "max": 3.0}
    assert s["robust/model_fit_checked"]["n"] == 1 and s["robust/model_fit_checked"]["mean"] == 0.5
    text = format_summary(rows, "dense_textured_mae")
    assert "2.000" in text and "px" in text
    assert metric_unit("sparse_outlier_fraction") == "fraction of pixels" and metric_unit("sparse_n") == "pixels"
    png = plot_metric(rows, "dense_textured_mae", tmp_path / "m.png")
    assert png.stat().st_size > 5000 and not list(tmp_path.glob(".m.png*"))


def test_bench_sweep_flag_runs_the_sweep_benchmark(tmp_path, monkeypatch):
    from repro import _sweep_bench, bench

    calls = []

    def fake(out, **kw):
        calls.append(out)
        (out / "sweep.md").parent.mkdir(parents=True, exist_ok=True)
        (out / "sweep.md").write_text("# Sweep engine benchmark\n")
        return {}

    monkeypatch.setattr(_sweep_bench, "run_sweep_bench", fake)
    assert bench.main(["--sweep", "--out", str(tmp_path)]) == 0
    assert calls == [tmp_path]


def test_procedural_scene_names_are_accepted_by_every_scene_axis():
    """procedural_<seed> names pass the scene check of the sweep grid and of the render CLIs;
    an unknown name is still refused, naming the procedural form too."""
    from repro._cli import check_scene_names

    assert check_scene_names(["planes", "procedural_100003", "procedural_7_nikon_d50_180mm"]) == [
        "planes", "procedural_100003", "procedural_7_nikon_d50_180mm"]
    assert check_scene_names(["procedural_2"]) == ["procedural_2"]
    with pytest.raises(ValueError, match=r"unknown scene.*'nope'.*or procedural_<seed>"):
        check_scene_names(["nope", "procedural_2"])
    with pytest.raises(ValueError, match="no scene"):
        check_scene_names([])


# --------------------------------------------------------------------------------------------------
# --force: every cell recomputed, none read back


class _EngineStarted(Exception):
    pass


def test_force_reads_nothing_back_from_the_case_store(tmp_path, monkeypatch):
    from experiments import cases
    from repro import _runner, sweep as mod
    from repro._sweep_engine import run_sweep
    from repro._sweep_grid import build_grid

    asked = []

    def refuse(*a, **kw):
        raise _EngineStarted

    monkeypatch.setattr(cases, "stored_case", lambda unit, config, case, **kw: asked.append(case))
    monkeypatch.setattr(_runner, "run_figures", refuse)
    grid = build_grid(scenes=["planes"], f_numbers=[8.0], estimators=["zero_crossing"],
                      params=[("alpha", (0.5, 2.0))])
    with pytest.raises(_EngineStarted):  # nothing stored: the store is asked for every case, then the runner starts
        run_sweep(grid, tmp_path, progress=False, log=lambda m: None)
    assert len(asked) == 2  # the two cells (their render case is a need of theirs)
    asked.clear()
    with pytest.raises(_EngineStarted):  # --force: the store is not even asked
        run_sweep(grid, tmp_path, progress=False, log=lambda m: None, force=True)
    assert asked == []
    assert mod._parser().parse_args(["--out", "x"]).force is False
    assert mod._parser().parse_args(["--out", "x", "--force"]).force is True
