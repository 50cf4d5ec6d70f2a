"""The case runner (:mod:`repro._runner`): Dask workers and this process give the same cases and the same
table, a killed worker loses no case, and a bad engine flag is one line with exit status 2."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PROG = "python -m repro.figures"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _figures(argv):
    from repro._cli import run_cli
    from repro.figures import main

    return run_cli(main, list(argv), prog=PROG)


@pytest.mark.parametrize("argv, needle", [
    (["--workers", "0"], "--workers/--jobs: '0' is invalid; allowed: integer >= 1"),
    (["--jobs", "-1"], "integer >= 1"),
    (["--scheduler", "tcp://127.0.0.1:{port}"], "unreachable"),
    (["--scheduler", "localhost:8786"], "tcp://HOST:PORT"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:{port}"], "not allowed with argument"),
])
def test_bad_engine_flags_are_one_line_exit_2_and_nothing_written(argv, needle, tmp_path, capsys, monkeypatch):
    from repro import _runner

    monkeypatch.setattr(_runner, "start_client", lambda **k: pytest.fail("an engine was started"))
    argv = [a.format(port=_free_port()) for a in argv]
    out = tmp_path / "out"
    assert _figures(["fig2", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()


def test_engine_choice():
    from repro._runner import dask_available, default_workers, engine_choice

    assert engine_choice(1, None, command="x") == (1, None)
    assert engine_choice(None, None, command="x") == ((default_workers() if dask_available() else 1), None)
    with pytest.raises(ValueError, match="exclusive"):
        engine_choice(2, "tcp://127.0.0.1:1", command="x")
    with pytest.raises(ValueError, match="allowed: integer >= 1"):
        engine_choice(0, None, command="x")


def test_order_cases_puts_needs_first_once():
    from experiments.cases import Case, order_cases

    a = Case("f", variant="a")
    b = Case("f", variant="b", needs=(a,))
    c = Case("f", variant="c", needs=(a, b))
    assert order_cases([c, b]) == [a, b, c]
    assert c.key()["needs"][1]["needs"] == [a.key()] and c.label == "f/c"


def _subset(fd, **fields):
    """The cases of ``fd`` matching ``fields`` and what they need."""
    from experiments.cases import order_cases

    return tuple(order_cases(o.case for o in fd.find(**fields)))


@pytest.mark.render
def test_dask_workers_give_the_serial_cases_and_rows(quick_figure):
    """A subset of fig5's and fig8's quick cases recomputed (``force``) on a LocalCluster of two workers:
    every metric, row and array equals the session's serial run of the same cases, bit for bit. fig8's is
    one deconvolution and the two cases it needs (its stage, then its map: a chain of needs across workers)."""
    from experiments.cases import case_rows
    from repro._runner import FigureJob, run_figures

    fig5, fig8 = quick_figure("fig5"), quick_figure("fig8")
    jobs = [FigureJob(fig5.figure, fig5.config, "quick", _subset(fig5, scene="patio_table", aperture=8.0)),
            FigureJob(fig8.figure, fig8.config, "quick", _subset(fig8, scene_set="tabletop_stress", preset="robust",
                                                                 variant="nsr=0.01"))]
    seen = []
    runs = run_figures(jobs, workers=2, force=True, progress=False, on_case=lambda job, out: seen.append(out.case),
                       log=lambda msg: None)
    for run, serial in zip(runs, (fig5, fig8)):
        assert run.error is None, run.traceback
        assert not any(o.cached for o in run.data.outputs.values())  # recomputed, on the workers
        assert list(run.data.outputs) == list(run.job.cases)
        for case, out in run.data.outputs.items():
            ref = serial.outputs[case]
            assert out.metrics == ref.metrics and out.groups == ref.groups, case.label
            a, b = out.arrays(), ref.arrays()
            assert set(a) == set(b)
            for k in a:
                np.testing.assert_array_equal(a[k], b[k], err_msg=f"{case.label}: {k}")
        rows = run.data.rows()
        labels = {c.label for c in run.job.cases}
        assert rows == [r for o in serial.outputs.values() if o.case.label in labels
                        for r in case_rows(o, evaluation_id=serial.evaluation_id)]
    assert sorted(c.label for c in seen) == sorted(c.label for j in jobs for c in j.cases)


@pytest.mark.render
@pytest.mark.slow
def test_a_killed_worker_loses_no_case(quick_figure, tmp_path):
    """``repro.figures fig10 --quick --force --scheduler ADDR`` on a scheduler with two workers; once a case is
    done, the worker running another case is SIGKILLed: the scheduler reruns that case on the other
    worker, the command finishes (exit 0) and its table equals the serial run's. fig10's three quick cases
    (the thin-lens edges, two procedural scenes' edges; renders cached) are the cheapest set of several
    cases that each run for seconds."""
    from dask.distributed import Client

    from experiments.results_query import read_table
    from tests.test_procedural_eval import _cluster, _stop

    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    address, procs = _cluster(tmp_path / "cluster", env)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "repro.figures", "fig10", "--quick", "--force", "-q", "--scheduler",
                             address, "--out", str(out)], cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)
    killed = None
    try:
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=180)
            deadline = time.monotonic() + 300
            while killed is None and proc.poll() is None and time.monotonic() < deadline:
                busy = [w for w, keys in client.processing().items()
                        if any(str(k).startswith("case-fig10-") for k in keys)]
                if busy and len(client.who_has()) > 1:  # a case is done and another one is running
                    pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
                    os.kill(pid, signal.SIGKILL)
                    killed = busy[0]
                time.sleep(0.05)
            stdout, stderr = proc.communicate(timeout=600)
    finally:
        _stop(proc)
        for p in reversed(procs):
            _stop(p)
    assert killed is not None, "no case was ever running on a worker"
    assert proc.returncode == 0, stderr[-3000:]
    serial = quick_figure("fig10")
    assert read_table(out).where(figure="fig10").rows == serial.rows()


def test_bench_figures_flag_runs_the_runner_benchmark(tmp_path, monkeypatch):
    from repro import _figures_bench, bench

    calls = []

    def fake(out, **kw):
        calls.append(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "figures_speed.md").write_text("# repro.figures with 1 and 2 workers\n")
        return {}

    monkeypatch.setattr(_figures_bench, "run_figures_bench", fake)
    assert bench.main(["--figures", "--out", str(tmp_path)]) == 0
    assert calls == [tmp_path]


def test_bench_accuracy_engine_flags_go_with_accuracy(capsys, tmp_path):
    from repro._cli import run_cli
    from repro.bench import PROG, main

    assert run_cli(main, ["--workers", "2", "--out", str(tmp_path / "b")], prog=PROG) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "go with --accuracy" in err


def test_the_runner_bench_compares_tables_without_wall_clock_times(tmp_path):
    """Two runs' tables differ in their times (unit s) always; in any other value only when a case differs."""
    from experiments.results_table import write_results
    from repro._figures_bench import _same_tables

    def table(folder, seconds, mae):
        rows = [{"evaluation_id": "fig7-quick-0", "source": "figures", "figure": "fig7", "metric": m, "value": v,
                 "unit": u} for m, v, u in (("compute_seconds", seconds, "s"), ("dense/mae", mae, "px (σ)"))]
        folder.mkdir()
        write_results(folder, rows, {})
        return folder

    ref = table(tmp_path / "w1", 3.0, 0.5)
    assert _same_tables(ref, table(tmp_path / "w2", 2.0, 0.5)) == (True, 1, [])
    assert _same_tables(ref, table(tmp_path / "w3", 3.0, 0.6)) == (False, 1, ["dense/mae"])
