"""All parameters of the defocus pipeline: one frozen dataclass per stage, composed by :class:`DefocusParams`.

Each stage's parameters live in (and are validated by) the stage's own subpackage, reading that
stage's registries:

=================  ==========================================  ===========================================
attribute          class                                       stage
=================  ==========================================  ===========================================
``edges``          :class:`method.edges.params.EdgeParams`      Sec. 3.1: edges, scales, noise, isolation
``blur``           :class:`method.blur.params.BlurParams`       Sec. 3.2, Eq. (2): blur at the edges
``region``         :class:`method.blur.params.RegionParams`     beyond the paper: blur over regions
``refinement``     :class:`method.refine.params.RefineParams`   Sec. 3.3, Eq. (3): cross-bilateral filter
``fusion``         :class:`method.propagation.params.FusionParams`       beyond the paper: cue fusion
``interpolation``  :class:`method.propagation.params.PropagationParams`  Sec. 4, Eq. (4): propagation
``magnification``  :class:`method.magnify.params.MagnifyParams`  Sec. 5: the map before magnification
=================  ==========================================  ===========================================

(``interpolation`` is not called ``propagation`` because that flat field names the propagation method.)
:class:`DefocusParams` adds the rules that span two stages. Field names are unique across stages, so
the parameters also form one flat namespace: ``params.alpha`` reads ``params.interpolation.alpha``,
``DefocusParams(alpha=0.3)`` and ``params.replace(alpha=0.3)`` set it, and for ``dataclasses`` (``fields``,
``asdict``, ``replace``) a :class:`DefocusParams` is the flat dataclass of every stage field, so cache
keys, ablation rows and ``--param FIELD=…`` address a field by its one name. Images are floats in [0, 1];
every blur quantity is a Gaussian σ in px of the input image. Named parameter sets: :mod:`method.presets`.
"""

from __future__ import annotations

import dataclasses
import operator

from .blur.params import BlurParams, RegionParams
from .edges.params import EdgeParams
from .magnify.params import MagnifyParams
from .propagation.params import FusionParams, PropagationParams
from .refine.params import RefineParams
from .registry import Registry
from .validation import invalid_field

__all__ = ["PRESETS", "DefocusParams"]

#: The stages, (attribute of DefocusParams, parameter dataclass), in pipeline order.
_STAGES = (("edges", EdgeParams), ("blur", BlurParams), ("region", RegionParams), ("refinement", RefineParams),
           ("fusion", FusionParams), ("interpolation", PropagationParams), ("magnification", MagnifyParams))

#: Named parameter sets, name -> DefocusParams (read by :meth:`DefocusParams.preset`). The sets
#: themselves are defined in :mod:`method.presets`, which fills this registry (and re-exports it).
PRESETS = Registry("preset")


class DefocusParams:
    """Every parameter of Bae & Durand 2007 (Sec. 3–5, Appendix B): one frozen dataclass per stage.

    ``DefocusParams()`` is the paper's method with its defaults (the ``paper`` preset).

    Parameters
    ----------
    edges, blur, region, refinement, fusion, interpolation, magnification : stage parameters, optional
        The stage dataclasses (the table of :mod:`method.params`); default: the stage's defaults.
    **fields
        Any stage field by its flat name (e.g. ``alpha=0.3``), applied on top of the stages given.

    Raises
    ------
    ValueError
        A bad field value, named as ``DefocusParams.<field>=… is invalid; allowed: …`` (each stage
        validates its own fields; the rules across two stages are checked here).
    TypeError
        An unknown keyword.

    Notes
    -----
    Frozen, hashable and compared by value. Flat attribute reads (``params.alpha``) are read-only
    properties generated from the stage dataclasses; :meth:`replace` makes a changed copy.
    """

    edges: EdgeParams
    blur: BlurParams
    region: RegionParams
    refinement: RefineParams
    fusion: FusionParams
    interpolation: PropagationParams
    magnification: MagnifyParams

    #: The flat dataclass protocol: ``dataclasses.fields`` / ``asdict`` / ``replace`` see every stage
    #: field by its flat name (the stages' own Field objects, so names, types and defaults are theirs).
    __dataclass_fields__ = {f.name: f for _, cls in _STAGES for f in dataclasses.fields(cls)}
    __dataclass_params__ = EdgeParams.__dataclass_params__  # frozen, compared by value, like every stage
    _stage_fields = {stage: tuple(f.name for f in dataclasses.fields(cls)) for stage, cls in _STAGES}

    def __init__(self, **fields):
        unknown = [n for n in fields if n not in self.__dataclass_fields__ and n not in self._stage_fields]
        if unknown:
            raise TypeError(f"DefocusParams.__init__() got an unexpected keyword argument {unknown[0]!r}")
        for stage, cls in _STAGES:
            given = fields.get(stage)
            changes = {n: fields[n] for n in self._stage_fields[stage] if n in fields}
            if given is None:
                value = cls(**changes)
            elif isinstance(given, cls):
                value = dataclasses.replace(given, **changes) if changes else given
            else:
                raise invalid_field(stage, given, f"an instance of {cls.__name__} (or None: its defaults)")
            object.__setattr__(self, stage, value)
        _check_across_stages(self)

    # --- frozen value semantics ----------------------------------------------------------------------
    def __setattr__(self, name, value):
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")

    def __delattr__(self, name):
        raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")

    def _stage_values(self) -> tuple:
        return tuple(self.__dict__[stage] for stage, _ in _STAGES)

    def __eq__(self, other):
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._stage_values() == other._stage_values()

    def __hash__(self):
        return hash(self._stage_values())

    def __repr__(self) -> str:
        return "DefocusParams(" + ", ".join(f"{stage}={self.__dict__[stage]!r}" for stage, _ in _STAGES) + ")"

    # --- the stages and the flat namespace -----------------------------------------------------------
    def stages(self) -> dict:
        """The stage parameters, {attribute: stage dataclass instance}, in pipeline order."""
        return {stage: self.__dict__[stage] for stage, _ in _STAGES}

    @classmethod
    def stage_classes(cls) -> dict:
        """The stage dataclasses, {attribute: class}, in pipeline order."""
        return dict(_STAGES)

    @classmethod
    def stage_of(cls, field: str) -> str:
        """The stage attribute holding the flat field ``field`` (ValueError naming the fields if unknown)."""
        for stage, names in cls._stage_fields.items():
            if field in names:
                return stage
        raise ValueError(f"DefocusParams field {field!r} is invalid (unknown); allowed: "
                         f"{', '.join(map(repr, cls.__dataclass_fields__))}")

    @classmethod
    def field_types(cls) -> dict:
        """Every flat field with its annotated type (as written, e.g. ``"float | None"``), in pipeline order."""
        return {name: f.type for name, f in cls.__dataclass_fields__.items()}

    def replace(self, **changes) -> "DefocusParams":
        """A validated copy with some fields (flat names) or whole stages changed."""
        return DefocusParams(**{**self.stages(), **changes}) if changes else self

    def changes_from(self, other: "DefocusParams") -> dict:
        """Fields whose value differs from ``other``: {flat name: (value here, value in other)}."""
        return {n: (getattr(self, n), getattr(other, n)) for n in self.__dataclass_fields__
                if getattr(self, n) != getattr(other, n)}

    @classmethod
    def preset(cls, name: str, **changes) -> "DefocusParams":
        """A named parameter set of :data:`PRESETS` (``"paper"``, ``"robust"``, ``"zhuo_sim"``), optionally changed.

        Parameters
        ----------
        name : str
            Key of :data:`PRESETS` (defined in :mod:`method.presets`).
        **changes
            Fields to override (flat names; validated).

        Raises
        ------
        ValueError
            Unknown name (the message lists the presets) or bad field values.
        """
        params = PRESETS.resolve(name, what="preset")
        return params.replace(**changes) if changes else params


def _check_across_stages(p: DefocusParams) -> None:
    """The rules that span two stages (each stage's own fields are checked by its dataclass)."""
    if p.edge_detector == "canny" and p.estimator != "gradient_ratio":
        raise invalid_field("edge_detector", p.edge_detector, "'canny' only with estimator='gradient_ratio' (the "
                            "other estimators read the Elder–Zucker σ2 scales); else 'elder_zucker'")
    if p.bias_weighting == "uncertainty" and p.measure_weighting != "uncertainty":
        raise invalid_field("bias_weighting", p.bias_weighting, "'uniform' unless measure_weighting='uncertainty' "
                            "(the bias follows each measure's own uncertainty)")
    if p.region_estimator is not None and p.propagation != "colorization":
        raise invalid_field("propagation", p.propagation, "'colorization' when region_estimator is set (the fusion "
                            "needs per-pixel data weights in Eq. 4)")


def _flat_properties() -> None:
    """Give :class:`DefocusParams` a read-only property per stage field (``params.alpha`` →
    ``params.interpolation.alpha``); a field name shared by two stages or shadowing a stage fails here."""
    n_fields = sum(len(names) for names in DefocusParams._stage_fields.values())
    if len(DefocusParams.__dataclass_fields__) != n_fields:
        raise TypeError("two parameter stages share a field name")
    for stage, cls in _STAGES:
        for name in DefocusParams._stage_fields[stage]:
            if name in DefocusParams._stage_fields or name in vars(DefocusParams):
                raise TypeError(f"the field {cls.__name__}.{name} shadows an attribute of DefocusParams")
            doc = f"``{stage}.{name}`` ({cls.__name__}); read-only, change it with :meth:`DefocusParams.replace`."
            setattr(DefocusParams, name, property(operator.attrgetter(f"{stage}.{name}"), doc=doc))


_flat_properties()
