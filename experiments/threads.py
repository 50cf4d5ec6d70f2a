"""One thread for BLAS and numba while a unit of work runs: the one definition of :func:`single_threaded`.

Cases, scenes and sweep cells are the parallelism (:mod:`repro._runner` runs them on Dask workers);
running each on one thread makes every number independent of how many run at once and of a worker's core
count, so serial and parallel tables agree. A leaf module: it imports no project package.
"""

from __future__ import annotations

import contextlib

__all__ = ["single_threaded"]


@contextlib.contextmanager
def single_threaded():
    """BLAS (threadpoolctl) and numba on one thread inside the block, restored after."""
    import numba
    from threadpoolctl import threadpool_limits

    old = numba.get_num_threads()
    with threadpool_limits(1):
        numba.set_num_threads(1)
        try:
            yield
        finally:
            numba.set_num_threads(old)
