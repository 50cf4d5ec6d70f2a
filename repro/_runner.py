"""The case runner: every case of the chosen figures on Dask workers, or one after another in this process.

:func:`run_figures` takes figure runs (:class:`FigureJob`: a figure, a config and its cases, see
:mod:`experiments.cases`) and computes every case through the figure cache
(:func:`experiments.cases.run_case`): on a Dask LocalCluster of single-threaded worker processes (one
per core by default) or an existing scheduler (:func:`_start_client`), one task per case — a case that
needs others takes their futures, so it waits for those tasks only — or, with one worker or without the ``sweep`` extra, in this process, needs first. Either
way each case runs with numba and BLAS on one thread and is stored in the cache as soon as it finishes,
so serial and parallel runs give the same numbers, a killed worker loses only the case it was running
(the scheduler reruns it elsewhere) and the same command again reads every finished case back.

Progress: a tqdm bar of cases done / total. As soon as every case of a figure is done, ``on_figure``
is called with its :class:`experiments.figure_data.FigureData` (``repro.figures`` plots it there, while
the workers compute the other figures' cases).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import os
import socket
import sys
import traceback
from collections.abc import Callable
from urllib.parse import urlparse

from ._cli_errors import CLIError

__all__ = ["FigureJob", "FigureRun", "add_engine_options", "check_scheduler", "default_workers", "dask_available",
           "engine_choice", "run_figures"]


@dataclasses.dataclass(frozen=True)
class FigureJob:
    """One figure run: the figure, its config, the mode label and the cases (default: all of the config's)."""

    figure: object
    config: object
    mode: str = "custom"
    cases: tuple | None = None

    def case_list(self) -> tuple:
        """The cases to run."""
        return tuple(self.cases) if self.cases is not None else self.figure.cases(self.config)


@dataclasses.dataclass
class FigureRun:
    """What became of one :class:`FigureJob`: its data, or the case that failed and its traceback."""

    job: FigureJob
    data: object = None  # experiments.figure_data.FigureData when every case finished
    error: str | None = None  # "<case label>: <Exception>: <message>"
    traceback: str | None = None


def dask_available() -> bool:
    """Whether ``dask.distributed`` (the ``sweep`` extra) can be imported."""
    try:
        return importlib.util.find_spec("dask.distributed") is not None
    except (ImportError, ValueError):
        return False


def default_workers() -> int:
    """One worker per core this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def add_engine_options(p, *, what: str = "cases") -> None:
    """``--workers N`` (alias ``--jobs``) and ``--scheduler ADDRESS`` (exclusive) on an argparse parser."""
    from repro._cli import int_type

    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", "--jobs", dest="workers", type=int_type("--workers"), default=None, metavar="N",
                   help=f"{what} computed in parallel: a Dask LocalCluster of N single-threaded worker processes "
                        "(default: one per core; 1: one after another in this process, as without the sweep "
                        "extra); --jobs is the same")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (its workers must see the same "
                        "$DEFOCUS_CACHE_DIR)")


def check_scheduler(address: str) -> None:
    """CLIError (one line) unless something accepts a TCP connection at ``tcp://HOST:PORT`` within 5 s."""
    url = urlparse(address)
    try:
        port = url.port
    except ValueError:
        port = None
    if url.scheme != "tcp" or not url.hostname or port is None:
        raise CLIError(f"--scheduler {address!r} is invalid; allowed: an address like tcp://HOST:PORT")
    try:
        socket.create_connection((url.hostname, port), timeout=5).close()
    except OSError as exc:
        raise CLIError(f"--scheduler {address} is unreachable ({exc.strerror or exc}); allowed: the address of a "
                         "running dask scheduler") from None


def engine_choice(workers: int | None, scheduler: str | None, *, command: str) -> tuple[int | None, str | None]:
    """``(workers, scheduler)`` to run with: validated (CLIError / a missing extra, one line each).

    ``workers`` None means one per core; with one worker, or without the ``sweep`` extra and no
    ``scheduler``, the cases run in this process (returned as ``workers = 1``).
    """
    if workers is not None and scheduler is not None:
        raise CLIError("--workers and --scheduler are exclusive; allowed: one of them")
    if workers is not None and workers < 1:
        raise CLIError(f"--workers {workers} is invalid; allowed: integer >= 1")
    if scheduler is not None:
        from repro._cli import require_extras

        require_extras("sweep", command=f"{command} --scheduler")
        check_scheduler(scheduler)
        return None, scheduler
    n = default_workers() if workers is None else workers
    if n > 1 and not dask_available():
        if workers is not None:
            print(f"{command}: the sweep extra (dask) is not installed: running the cases one after another in this "
                  "process", file=sys.stderr)
        n = 1
    return n, None


def run_figures(jobs, *, workers: int | None = 1, scheduler: str | None = None, force: bool = False,
                progress: bool = True, on_figure: Callable | None = None, on_case: Callable | None = None,
                log=None, desc: str = "cases") -> list[FigureRun]:
    """Compute every case of ``jobs`` (in this process for ``workers == 1``, else on Dask).

    Parameters
    ----------
    jobs : sequence of FigureJob
    workers : int, optional, keyword-only
        1: in this process; N > 1: a LocalCluster of N single-threaded workers; None: one per core.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler (instead of a LocalCluster).
    force : bool, keyword-only
        Recompute every case (each once).
    progress : bool, keyword-only
        tqdm bar of cases done / total.
    on_figure : callable, optional, keyword-only
        ``on_figure(FigureRun)`` as soon as a figure's cases are all done (or one failed).
    on_case : callable, optional, keyword-only
        ``on_case(FigureJob, CaseOutput)`` as each case comes back (e.g. to store it for a resume).
    desc : str, keyword-only
        Label of the progress bar.
    log : callable, optional, keyword-only
        One-line messages (default: stderr).

    Returns
    -------
    list of FigureRun
        In the order of ``jobs``.
    """
    from tqdm import tqdm

    from experiments.cases import order_cases

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    plans = [(job, order_cases(job.case_list())) for job in jobs]
    total = sum(len(cases) for _, cases in plans)
    runs = [FigureRun(job=job) for job in jobs]
    hooks = {"on_figure": on_figure, "on_case": on_case}
    with tqdm(total=total, desc=desc, unit="case", file=sys.stderr, disable=not progress,
              dynamic_ncols=True) as bar:
        if scheduler is None and (workers or default_workers()) <= 1:
            _run_here(plans, runs, force=force, bar=bar, **hooks)
        else:
            _run_dask(plans, runs, workers=workers, scheduler=scheduler, force=force, bar=bar, log=log, **hooks)
    return runs


def _finish(run: FigureRun, outputs: dict, cases) -> None:
    from experiments.figure_data import FigureData

    run.data = FigureData(figure=run.job.figure, config=run.job.config, outputs={c: outputs[c] for c in cases},
                          mode=run.job.mode)


def _run_here(plans, runs, *, force, bar, on_figure, on_case) -> None:
    """Every case in this process, needs first; a failing case fails its figure (the others go on)."""
    from experiments.cases import run_case

    for (job, cases), run in zip(plans, runs):
        outputs: dict = {}
        try:
            for c in cases:
                bar.set_postfix_str(c.label, refresh=False)
                outputs[c] = run_case(job.figure, job.config, c, outputs, force=force)
                if on_case is not None:
                    on_case(job, outputs[c])
                bar.update(1)
        except Exception as exc:  # noqa: BLE001 - one figure's failure is reported; the others still run
            run.error = f"{c.label}: {type(exc).__name__}: {exc}"
            run.traceback = "".join(traceback.format_exception(exc))
        else:
            _finish(run, outputs, cases)
        if on_figure is not None:
            on_figure(run)


def _start_client(*, workers: int | None, scheduler: str | None):
    """A Dask client on a new LocalCluster (``workers`` single-threaded processes) or an existing scheduler."""
    import logging

    from dask.distributed import Client, LocalCluster

    from repro._cli_errors import CLIError

    if scheduler:
        client = Client(scheduler, timeout="20s")
        try:
            client.wait_for_workers(1, timeout=60)
        except (TimeoutError, OSError):
            client.close()
            raise CLIError(f"--scheduler {scheduler}: no worker connected within 60 s; "
                             "allowed: a scheduler with workers (dask worker ADDRESS)") from None
        return client, None
    n = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    import dask

    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers to hand freed memory back at once; setting it
    # switches off glibc's adaptive mmap threshold, so every large numpy array is mapped and faulted in
    # afresh (measured: a third of the workers' CPU time spent in the kernel). The workers keep glibc's
    # defaults; the single-thread BLAS/OpenMP settings stay.
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    dask.config.set({"distributed.nanny.pre-spawn-environ": environ})
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


def _run_dask(plans, runs, *, workers, scheduler, force, bar, on_figure, on_case, log) -> None:
    """One Dask task per case (needs as futures); figures finish as their last case comes back."""
    from dask.distributed import as_completed

    from experiments.cases import case_task, task_key

    client, cluster = _start_client(workers=workers, scheduler=scheduler)
    try:
        n_workers = len(client.scheduler_info()["workers"]) if scheduler else len(cluster.workers)
        log(f"engine: {scheduler or 'LocalCluster'} with {n_workers} worker(s); dashboard: {client.dashboard_link}")
        owner, futures, remaining = {}, [], []
        for i, (job, cases) in enumerate(plans):
            futs: dict = {}
            for c in cases:
                futs[c] = client.submit(case_task, job.figure.name, job.config, c, *(futs[n] for n in c.needs),
                                        force=force, key=task_key(job.figure, job.config, c), pure=False)
                owner[futs[c].key] = (i, c)
                futures.append(futs[c])
            remaining.append({"futures": futs, "left": len(cases), "outputs": {}})
        for fut in as_completed(futures):
            i, c = owner[fut.key]
            state, run = remaining[i], runs[i]
            bar.set_postfix_str(c.label, refresh=False)
            bar.update(1)
            if run.error is not None:
                continue
            if fut.status == "error":
                exc = fut.exception()
                run.error = f"{c.label}: {type(exc).__name__}: {exc}"
                run.traceback = "".join(traceback.format_exception(type(exc), exc, fut.traceback()))
                if on_figure is not None:
                    on_figure(run)
                continue
            state["outputs"][c] = fut.result()
            if on_case is not None:
                on_case(run.job, state["outputs"][c])
            state["left"] -= 1
            if state["left"] == 0:
                _finish(run, state["outputs"], plans[i][1])
                if on_figure is not None:
                    on_figure(run)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
