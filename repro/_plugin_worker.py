"""The Dask side of :mod:`repro._plugins`: a worker plugin that registers the client's plugins in each
worker's process, and :func:`install_on_workers`, which sends it and checks the workers' registries.

Its own module because it imports ``distributed`` (the ``sweep`` extra) at module level, as a
:class:`~distributed.diagnostics.plugin.WorkerPlugin` subclass must be importable on the worker by reference.
"""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

from ._cli_errors import CLIError
from ._plugins import ENTRY_POINT_GROUPS, FLAGS, load_worker_plugins, loaded_specs, registered_names, registry_of

__all__ = ["LoadPlugins", "install_on_workers"]


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
        load_worker_plugins(self.specs)


def install_on_workers(client) -> None:
    """Make ``client``'s workers (also those that join later) import this process's plugins by import path.

    Raises
    ------
    repro._cli_errors.CLIError
        A worker could not load one (its environment lacks the package), or this process has names the
        workers do not (registered here by other means than an import path).
    """
    specs = [(s.kind, s.text) for s in loaded_specs()]
    try:
        client.register_plugin(LoadPlugins(specs))
    except Exception as exc:  # noqa: BLE001 - a worker's environment, not this computation
        raise CLIError(f"the Dask workers could not load the plugins ({type(exc).__name__}: "
                       f"{' '.join(str(exc).split())}); allowed: workers whose Python has the same packages "
                       "installed") from exc
    here = registered_names()
    for worker, names in client.run(registered_names).items():
        for kind, mine in here.items():
            missing = [n for n in mine if n not in names[kind]]
            if missing:
                raise CLIError(
                    f"{registry_of(kind).kind}(s) {', '.join(map(repr, missing))} registered in this process are "
                    f"unknown on the Dask worker {worker}; allowed: entries registered by import path "
                    f"({FLAGS[kind]} package.module:attribute or the entry-point group "
                    f"{ENTRY_POINT_GROUPS[kind]}), or --workers 1 (in this process)")
