"""The Dask worker plugin that registers the harness's plugins in each worker's process (``repro._plugins``).

Its own module because it imports ``distributed`` (the ``sweep`` extra) at module level, as a
:class:`~distributed.diagnostics.plugin.WorkerPlugin` subclass must be importable on the worker by reference.
"""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

__all__ = ["LoadPlugins"]


class LoadPlugins(WorkerPlugin):
    """Registers the entry points and the given specs in a worker's process, when it starts or joins.

    Parameters
    ----------
    specs : sequence of (str, str)
        ``(kind, "NAME=package.module:attribute")`` per plugin loaded in the client's process.
    """

    name = "defocus-repro-plugins"

    def __init__(self, specs):
        self.specs = tuple(tuple(s) for s in specs)

    def setup(self, worker):  # noqa: D102 - distributed hook
        from repro._plugins import load_worker_plugins

        load_worker_plugins(self.specs)
