"""The documented cluster recipe (README.md or docs/), run as written: ``dask scheduler`` and
``dask worker`` started outside the checkout, with the worker's default local directory, against the
editable install.

What this guards: a Dask worker puts its local directory on ``sys.path`` (first), and that directory holds
a spill folder named ``storage/``. A top-level project package of that name was shadowed by the empty
folder (a namespace package), so the first render task died with ``ImportError: cannot import name
'CACHE_ENV' from 'storage' (unknown location)``. The tests of ``tests/test_sweep.py`` did not see it:
they start workers with the checkout as working directory and their own ``--local-directory``. Here the
worker's working directory is a temporary folder that also holds a ``storage/`` folder, no
``--local-directory`` is given, and the worker runs the two functions ``repro.sweep`` submits
(:func:`experiments.sweep_cells.render_task` and :func:`~experiments.sweep_cells.cell_task`, imported
on the worker by reference). Checked to fail on the code before the cache package was renamed to
``defocus_cache`` (the same steps with the package named ``storage``) and to pass after.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")  # the 'sweep' extra

ROOT = Path(__file__).resolve().parents[1]

#: Seconds to wait for the scheduler to listen, for the worker to register, for the two tasks.
#: Measured on the shared 2-core machine: scheduler ≈ 3 s, worker ≈ 5 s, tasks ≈ 5 s with the render cached.
START_TIMEOUT_S = 120
TASK_TIMEOUT_S = 600
#: The project packages a sweep task imports on the worker.
PACKAGES = ("defocus_cache", "method", "scenes", "experiments")


def _documented_worker_flags() -> list[str]:
    """The flags of the documented ``dask worker tcp://SCHEDULER:PORT ...`` line (README.md or docs/),
    with ``--nworkers`` set to 1 (this machine is small)."""
    pattern = re.compile(r"^\s*dask worker tcp://SCHEDULER:\d+((?:\s+--[\w-]+\s+[^\s#]+)*)", re.M)
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        m = pattern.search(page.read_text(encoding="utf-8"))
        if m:
            flags = m.group(1).split()
            assert "--local-directory" not in flags, "the recipe sets a local directory: test that instead"
            if "--nworkers" in flags:
                flags[flags.index("--nworkers") + 1] = "1"
            return flags
    raise AssertionError("no 'dask worker tcp://SCHEDULER:PORT ...' recipe in README.md or docs/*.md")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_cli() -> str:
    """The ``dask`` console script of this environment (the one the editable install is in)."""
    exe = Path(sys.executable).with_name("dask")
    if not exe.exists():
        pytest.skip(f"no dask console script next to {sys.executable}")
    return str(exe)


def _stop(proc: subprocess.Popen) -> None:
    """End the process group this test started: SIGTERM (the nanny stops its worker), then SIGKILL."""
    for sig, wait in ((signal.SIGTERM, 15), (signal.SIGKILL, 10)):
        try:
            os.killpg(proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


#: Evaluated on the worker (``eval`` is pickled by reference; a function of this module could not be
#: imported there): where the project's packages come from, the worker's cwd and the head of ``sys.path``.
WHERE_IMPORTED = ("{'cwd': __import__('os').getcwd(), 'sys_path_head': __import__('sys').path[:3], "
                  "'spill_folder': __import__('os').path.isdir(__import__('sys').path[0] + '/storage'), "
                  "**{n: getattr(__import__('importlib').import_module(n), '__file__', None) for n in %r}}"
                  % (PACKAGES,))


@pytest.mark.slow
def test_readme_cluster_recipe_outside_the_checkout_runs_a_sweep_render_and_cell(tmp_path):
    from dask.distributed import Client

    from experiments.sweep_cells import cell_task, render_task

    worker_flags = _documented_worker_flags()
    outside = tmp_path / "elsewhere"
    (outside / "storage").mkdir(parents=True)  # as a worker's spill folder would be
    assert ROOT not in outside.parents
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp"), "PYTHONUNBUFFERED": "1"}
    env.pop("PYTHONPATH", None)  # only the editable install may find the project
    (tmp_path / "tmp").mkdir()
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = _dask_cli()
    logs = {name: open(tmp_path / f"{name}.log", "wb") for name in ("scheduler", "worker")}
    procs = []
    try:
        procs.append(subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                       "--dashboard-address", "127.0.0.1:0"],
                                      cwd=outside, env=env, stdout=logs["scheduler"], stderr=subprocess.STDOUT,
                                      start_new_session=True))
        procs.append(subprocess.Popen([dask, "worker", address, *worker_flags],
                                      cwd=outside, env=env, stdout=logs["worker"], stderr=subprocess.STDOUT,
                                      start_new_session=True))
        with Client(address, timeout=f"{START_TIMEOUT_S}s") as client:
            client.wait_for_workers(1, timeout=START_TIMEOUT_S)
            render = client.submit(render_task, "planes", f_number=8.0, scene_preset="small", pure=False)
            cell = client.submit(cell_task, render, scene="planes", f_number=8.0, scene_preset="small",
                                 method_preset="paper", pure=False)
            info, row = render.result(timeout=TASK_TIMEOUT_S), cell.result(timeout=TASK_TIMEOUT_S)
            where = client.submit(eval, WHERE_IMPORTED, pure=False).result(timeout=START_TIMEOUT_S)
    finally:
        for p in reversed(procs):
            _stop(p)
        for f in logs.values():
            f.close()
    # the worker ran outside the checkout, with its default local directory first on sys.path ...
    assert Path(where["cwd"]) == outside
    local_dir = Path(where["sys_path_head"][0])
    assert (tmp_path / "tmp") in local_dir.parents, where
    assert where["spill_folder"], "the worker's spill folder storage/ is not in its local directory"
    # ... and still imported the project from the editable install (the checkout), not from a folder
    for name in PACKAGES:
        assert where[name] is not None and ROOT in Path(where[name]).parents, (name, where)
    assert Path(info["path"]).is_file() and info["variant"]
    assert row["metrics"], row
