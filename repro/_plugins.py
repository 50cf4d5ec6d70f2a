"""Blur estimators and presets of other packages, registered by import path in this process and on every Dask worker.

Two ways in, both naming an object by import path ``package.module:attribute``:

- **entry points** of an installed distribution (its ``pyproject.toml``)::

      [project.entry-points."defocus_repro.estimators"]
      my_idea = "my_pkg.blur:estimate_blur_my_idea"     # fn(gray, edge_map, *, params) -> σ map
      [project.entry-points."defocus_repro.presets"]
      my_preset = "my_pkg.presets:MY_PRESET"            # a method.DefocusParams

  loaded by every tool that evaluates the method (``repro.figures``, ``evaluate``, ``sweep``, ``bench``)
  as it parses its flags;
- the flags ``--estimator-module [NAME=]package.module:function`` and ``--preset-module
  [NAME=]package.module:ATTRIBUTE`` (repeatable; NAME defaults to the attribute's name) of the same tools
  (:func:`repro._cli.add_plugin_options`).

The object is a function (estimators) or a :class:`method.DefocusParams` (presets), or a
:class:`method.registry.Entry` of one (summary, capabilities, hooks); a preset may also be a function of no
arguments returning one, called once the estimators are registered (so its parameters may name an
estimator of the same package: entry points of estimators load before those of presets, and
``--estimator-module`` before ``--preset-module``). It is registered with
:meth:`method.registry.Registry.register` into :data:`method.BLUR_ESTIMATORS` / :data:`method.PRESETS`
(a name that is taken is refused). Every Dask worker the harness starts or joins
(:func:`repro._plugin_worker.install_on_workers`, called by ``repro._runner.start_client``) imports
the same import paths itself, through a worker plugin, also workers that join later: the registries are never pickled.
Before any task is submitted the workers' registries are compared with this process's, so an entry
registered here by other means (``BLUR_ESTIMATORS["x"] = f`` in a script) is one clear error instead of
tasks failing on the workers.

Bad input (a spec that is not ``[NAME=]module:attribute``, a module that does not import or raises on
import, an attribute it lacks or of the wrong kind, a taken name, a broken entry point): ValueError, one
line naming what is allowed; the CLIs show it as one line and exit status 2. A bug inside a registered
estimator is not caught here: it shows its traceback when the estimator runs.
"""

from __future__ import annotations

import dataclasses
import importlib
import re

__all__ = ["ENTRY_POINT_GROUPS", "FLAGS", "PluginSpec", "load_entry_points", "load_plugins",
           "load_worker_plugins", "loaded_specs", "parse_spec", "plugin_argv", "register_spec", "registered_names", "registry_of"]

#: kind -> entry-point group.
ENTRY_POINT_GROUPS = {"estimator": "defocus_repro.estimators", "preset": "defocus_repro.presets"}
#: kind -> the command-line flag that names one by import path.
FLAGS = {"estimator": "--estimator-module", "preset": "--preset-module"}
#: What a registered name may look like (it appears in flags, tables and file names).
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
_PATH = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")
#: Specs loaded in this process, in order (what the workers and subprocesses load again).
_LOADED: dict = {}


@dataclasses.dataclass(frozen=True)
class PluginSpec:
    """One object to register: its kind, the name it gets and its import path."""

    kind: str       # "estimator" or "preset"
    name: str
    module: str     # package.module
    attribute: str  # attribute (dotted for a nested one)
    origin: str = ""  # where the spec came from, for messages ("--estimator-module ..." or the entry point)

    @property
    def text(self) -> str:
        """``NAME=package.module:attribute`` (what the flag takes)."""
        return f"{self.name}={self.module}:{self.attribute}"


def registry_of(kind: str):
    """The registry of ``kind``: :data:`method.BLUR_ESTIMATORS` ("estimator") or :data:`method.PRESETS` ("preset")."""
    from method import BLUR_ESTIMATORS, PRESETS

    return {"estimator": BLUR_ESTIMATORS, "preset": PRESETS}[kind]


def _allowed_value(kind: str) -> str:
    if kind == "estimator":
        return "a function fn(gray, edge_map, *, params) -> σ map (px), or a method.registry.Entry of one"
    return "a method.DefocusParams, a method.registry.Entry of one, or a function of no arguments returning one"


def parse_spec(text: str, *, kind: str, origin: str | None = None) -> PluginSpec:
    """The :class:`PluginSpec` of ``[NAME=]package.module:attribute``.

    Parameters
    ----------
    text : str
        The spec as the user wrote it; NAME defaults to the attribute's last part.
    kind : {"estimator", "preset"}, keyword-only
    origin : str, optional, keyword-only
        How messages name the spec (default: the kind's flag and ``text``).

    Raises
    ------
    ValueError
        ``text`` is not of that form, or NAME is not a plain name.
    """
    if kind not in FLAGS:
        raise ValueError(f"kind={kind!r} is invalid; allowed: {', '.join(FLAGS)}")
    origin = origin or f"{FLAGS[kind]} {text}"
    name, sep, path = str(text).strip().rpartition("=")
    module, colon, attribute = path.strip().partition(":")
    module, attribute, name = module.strip(), attribute.strip(), name.strip()
    if not colon or not _PATH.match(module) or not _PATH.match(attribute):
        what = "function" if kind == "estimator" else "ATTRIBUTE"
        raise ValueError(f"{origin} is invalid; allowed: [NAME=]package.module:{what} (an import path, e.g. "
                         "my_pkg.blur:estimate_blur_my_idea)")
    name = name if sep else attribute.rpartition(".")[2]
    if not _NAME.match(name):
        raise ValueError(f"{origin}: name {name!r} is invalid; allowed: letters, digits, '_' and '-', not first "
                         "a digit")
    return PluginSpec(kind, name, module, attribute, origin)


def _import_object(spec: PluginSpec):
    """The object ``spec`` names (ValueError, one line, when its module does not import or lacks it)."""
    try:
        obj = importlib.import_module(spec.module)
    except Exception as exc:  # noqa: BLE001 - whatever a plugin raises on import is the user's to fix
        raise ValueError(f"{spec.origin}: module {spec.module!r} does not import ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())}); allowed: a module importable by this Python (installed "
                         "or on PYTHONPATH) that imports without error (--debug shows its traceback)") from exc
    for part in spec.attribute.split("."):
        if not hasattr(obj, part):
            public = sorted(n for n, v in vars(obj).items() if not n.startswith("_") and
                            getattr(v, "__module__", spec.module) == spec.module and not isinstance(v, type(re)))
            shown = ", ".join(public[:8]) + (", ..." if len(public) > 8 else "")
            raise ValueError(f"{spec.origin}: {spec.module!r} has no attribute {spec.attribute!r}; allowed: a name "
                             f"defined in it ({shown or 'none'})")
        obj = getattr(obj, part)
    return obj


def _check_value(spec: PluginSpec, obj):
    """``obj`` if it is of ``spec``'s kind (a plain value or an Entry of one; a preset may also be a function
    of no arguments returning one, called here); else ValueError."""
    from method import DefocusParams
    from method.registry import Entry

    if spec.kind == "preset" and callable(obj) and not isinstance(obj, (Entry, DefocusParams, type)):
        try:  # a factory: its params may name estimators registered just before (entry points load those first)
            obj = obj()
        except Exception as exc:  # noqa: BLE001 - a preset that cannot be built is the user's to fix
            raise ValueError(f"{spec.origin}: {spec.module}:{spec.attribute}() raised {type(exc).__name__}: "
                             f"{' '.join(str(exc).split())}; allowed: {_allowed_value(spec.kind)}") from exc
    value = obj.value if isinstance(obj, Entry) else obj
    if spec.kind == "estimator":
        good = callable(value) and not isinstance(value, type)
    else:
        good = isinstance(value, DefocusParams)
    if not good:
        raise ValueError(f"{spec.origin}: {spec.module}:{spec.attribute} is a {type(value).__name__}; allowed: "
                         f"{_allowed_value(spec.kind)}")
    return obj


def register_spec(spec: PluginSpec):
    """Import what ``spec`` names and register it (:meth:`method.registry.Registry.register`); its Entry.

    Raises
    ------
    ValueError
        The module does not import, lacks the attribute, the object is of the wrong kind, or the name is
        registered with something else.
    """
    obj = _check_value(spec, _import_object(spec))
    try:
        entry = registry_of(spec.kind).register(spec.name, obj)
    except ValueError as exc:
        raise ValueError(f"{spec.origin}: {exc}") from None
    _LOADED[(spec.kind, spec.name)] = spec
    return entry


def load_entry_points() -> list[PluginSpec]:
    """Register every entry point of :data:`ENTRY_POINT_GROUPS` of the installed distributions.

    Raises
    ------
    ValueError
        One of them is malformed, does not import (or raises on import), names nothing of its kind, or
        takes a registered name; the message names the entry point and its distribution.
    """
    from importlib.metadata import entry_points

    specs = []
    for kind, group in ENTRY_POINT_GROUPS.items():
        for ep in sorted(entry_points(group=group), key=lambda e: e.name):
            dist = getattr(getattr(ep, "dist", None), "name", None)
            origin = f"entry point {ep.name} = {ep.value} (group {group}{', distribution ' + dist if dist else ''})"
            spec = parse_spec(f"{ep.name}={ep.value}", kind=kind, origin=origin)
            register_spec(spec)
            specs.append(spec)
    return specs


def load_plugins(estimators=(), presets=(), *, entry_points: bool = True) -> list[PluginSpec]:
    """Register the entry points (unless ``entry_points=False``), then the specs given by flag.

    Parameters
    ----------
    estimators, presets : sequence of str or PluginSpec
        ``[NAME=]package.module:attribute`` of ``--estimator-module`` / ``--preset-module``.
    entry_points : bool, keyword-only

    Returns
    -------
    list of PluginSpec
        What was registered (a spec registered before is registered again as a no-op).

    Raises
    ------
    ValueError
        As :func:`parse_spec`, :func:`register_spec` and :func:`load_entry_points`.
    """
    out = load_entry_points() if entry_points else []
    for kind, texts in (("estimator", estimators), ("preset", presets)):
        for text in texts or ():
            spec = text if isinstance(text, PluginSpec) else parse_spec(text, kind=kind)
            register_spec(spec)
            out.append(spec)
    return out


def loaded_specs() -> tuple[PluginSpec, ...]:
    """Every spec registered in this process so far (entry points and flags), in order."""
    return tuple(_LOADED.values())


def plugin_argv() -> list[str]:
    """``--estimator-module NAME=... --preset-module NAME=...`` of every spec loaded in this process: the
    arguments that give a subprocess of a tool the same registries (entry points load there anyway)."""
    return [a for s in _LOADED.values() for a in (FLAGS[s.kind], s.text)]


def registered_names() -> dict[str, list[str]]:
    """kind -> the names registered in this process (what a worker reports to the client)."""
    return {kind: list(registry_of(kind)) for kind in FLAGS}


def load_worker_plugins(specs) -> None:
    """On a worker: the entry points, then ``specs`` (tuples ``(kind, NAME=module:attribute)``)."""
    load_plugins(entry_points=True)
    for kind, text in specs:
        register_spec(parse_spec(text, kind=kind))
