"""Variants chosen by name: one registry type for every choice of the method.

Every option that names a variant — a blur estimator, a solver, a kernel family, a preset — is a key
of a :class:`Registry`. ``REGISTRY[name]`` gives what the name selects (the implementing function, or
for a preset its :class:`~method.params.DefocusParams`), so call sites read like a dict lookup;
:meth:`Registry.entry` gives the whole :class:`Entry`: a one-line summary, the capabilities the variant
has beyond the common signature, and the hooks (functions) that implement them. Validation
(``DefocusParams``), the CLIs' help and choice checks and the error messages all read the registry, so
a new variant is one function plus one entry, e.g.::

    BLUR_ESTIMATORS["my_idea"] = Entry(estimate_blur_my_idea, "what it computes (reference)")

From outside the package, :meth:`Registry.register` adds a name and refuses one that is taken (the
harness registers estimators and presets of other packages this way: ``repro._plugins``).
The error for an unknown name is written once, here (:meth:`Registry.check`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Entry", "Registry"]


@dataclass(frozen=True)
class Entry:
    """What one name of a :class:`Registry` selects.

    Attributes
    ----------
    value : callable or object or None
        The implementation (a function with the registry's signature), a value such as a parameter
        set, or None for a choice whose behaviour lives in the code that reads it.
    summary : str
        One line: what the variant computes, with its reference.
    capabilities : frozenset of str
        What the variant can do beyond the registry's common signature (e.g. ``"confidence"``);
        every key of ``hooks`` is one.
    hooks : mapping str -> callable
        The functions implementing capabilities that need one, by capability name.
    """

    value: Any = None
    summary: str = ""
    capabilities: frozenset = frozenset()
    hooks: Mapping[str, Callable] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "hooks", dict(self.hooks))
        object.__setattr__(self, "capabilities", frozenset(self.capabilities) | frozenset(self.hooks))


def _as_entry(value) -> Entry:
    """An :class:`Entry` as given, a string as a summary-only choice, anything else as the value."""
    if isinstance(value, Entry):
        return value
    if isinstance(value, str):
        return Entry(summary=value)
    doc = value.__doc__ if callable(value) else None
    return Entry(value, (doc or "").strip().split("\n", 1)[0])


class Registry(MutableMapping):
    """Names of one kind of variant, in registration order, each with its :class:`Entry`.

    Parameters
    ----------
    kind : str
        What the names are, for messages (e.g. ``"blur estimator"``).
    entries : mapping str -> Entry, callable, str or None, or iterable of str
        The variants. A callable (or other object) becomes ``Entry(value)``, a string a summary-only
        choice, and an iterable of names summary-less choices.

    Notes
    -----
    As a mapping it is name -> ``entry.value``, so ``REGISTRY[name](...)``, ``name in REGISTRY``,
    ``sorted(REGISTRY)`` and ``monkeypatch.setitem(REGISTRY, name, fn)`` work as on a dict; assigning
    a plain value registers it without capabilities.
    """

    def __init__(self, kind: str, entries: Mapping | Iterable[str] = ()):
        self.kind = str(kind)
        items = entries.items() if isinstance(entries, Mapping) else ((n, None) for n in entries)
        self._entries: dict[str, Entry] = {}
        self._registered: set[str] = set()  # names added by register(): other packages' (plugin_names)
        for name, value in items:
            self[name] = value

    # --- mapping protocol: name -> value ------------------------------------------------------
    def __getitem__(self, name):
        return self._entries[name].value

    def __setitem__(self, name, value):
        if not isinstance(name, str) or not name:
            raise ValueError(f"{self.kind} name={name!r} is invalid; allowed: a non-empty str")
        self._entries[name] = _as_entry(value)

    def __delitem__(self, name):
        del self._entries[name]
        self._registered.discard(name)

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name) -> bool:
        return isinstance(name, str) and name in self._entries

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._entries)})"

    def register(self, name: str, value) -> Entry:
        """Add ``name`` -> ``value`` (an :class:`Entry` or anything the constructor takes) unless it is taken.

        Registering the very entry a name already has again is a no-op (a plugin module loaded twice).

        Returns
        -------
        Entry
            The registered entry.

        Raises
        ------
        ValueError
            ``name`` is not a non-empty str, or it is registered with another entry (the message names
            the registered names).
        """
        entry = _as_entry(value)
        if name in self:
            old = self._entries[name]
            if old == entry or (old.value is entry.value and entry.value is not None and not isinstance(value, Entry)):
                return old
            raise ValueError(f"{self.kind} name={name!r} is invalid (already registered: "
                             f"{old.summary or old.value!r}); allowed: a name not in {self.allowed()}")
        self[name] = entry
        self._registered.add(name)
        return self._entries[name]

    def plugin_names(self) -> tuple[str, ...]:
        """The names added by :meth:`register` (other packages' variants, which the caches key by value)."""
        return tuple(n for n in self._entries if n in self._registered)

    # --- what validation, CLIs and messages read ----------------------------------------------
    def entry(self, name: str) -> Entry:
        """The :class:`Entry` of ``name`` (ValueError naming the allowed names if unknown)."""
        return self._entries[self.check(name)]

    def allowed(self) -> str:
        """The registered names, sorted, as they appear in error messages: ``'a', 'b'``."""
        return ", ".join(repr(n) for n in sorted(self._entries))

    def check(self, name, *, what: str | None = None, optional: bool = False):
        """``name`` if registered (or None with ``optional``); else ValueError naming the allowed values.

        Parameters
        ----------
        name : str or None
            The name to check.
        what : str, keyword-only
            How the caller spells the option in the message (e.g. ``"DefocusParams.estimator"``,
            ``"--kernel"``); default the registry's kind.
        optional : bool, keyword-only
            Accept None (the variant switched off).
        """
        if (optional and name is None) or name in self:
            return name
        allowed = ("None, " if optional else "") + self.allowed()
        raise ValueError(f"{what or self.kind}={name!r} is invalid (unknown {self.kind}); allowed: {allowed}")

    def check_all(self, names: Iterable[str], *, what: str | None = None) -> list[str]:
        """``names`` as a list if it is non-empty and every one is registered; else one ValueError.

        The message names every unknown name at once (``unknown preset(s) 'a', 'b'; allowed: ...``).
        """
        names = list(names)
        bad = [n for n in names if n not in self]
        if bad:
            raise ValueError(f"unknown {what or self.kind}(s) {', '.join(map(repr, bad))}; allowed: {self.allowed()}")
        if not names:
            raise ValueError(f"no {what or self.kind} given; allowed: {self.allowed()}")
        return names

    def resolve(self, name, *, what: str | None = None):
        """The value registered for ``name`` (ValueError naming the allowed names if unknown)."""
        return self._entries[self.check(name, what=what)].value

    def having(self, capability: str) -> frozenset[str]:
        """Names whose entries have ``capability``."""
        return frozenset(n for n, e in self._entries.items() if capability in e.capabilities)

    def hook(self, name: str, capability: str) -> Callable | None:
        """The hook implementing ``capability`` for ``name``; None when that entry has none."""
        return self.entry(name).hooks.get(capability)

    def describe(self) -> str:
        """``name (summary)`` per entry, comma-separated, for a CLI's help."""
        return ", ".join(f"{n} ({e.summary})" if e.summary else n for n, e in self._entries.items())
