"""The grid of an experiment sweep (``python -m repro.sweep``): renders, cells, ``--param`` values.

:func:`build_grid` validates every axis (scenes, cameras, f-numbers, seeds, method presets,
estimators, parameter values, encodings, the metric, the Mitsuba variant) and enumerates the cells:
the product render × method preset × estimator × parameter values × encoding, one :class:`Render`
per distinct (scene, camera, f-number, scene preset, seed). Nothing is rendered or submitted.
"""

from __future__ import annotations

import dataclasses
import itertools

__all__ = ["DEFAULT_METRIC", "INFO_COLUMNS", "INPUT_COLUMNS", "SCENE_CAMERA", "Cell", "Grid", "Render",
           "build_grid", "parse_param_value", "parse_params"]

#: Input columns of ``results.parquet`` before the swept parameter columns.
INPUT_COLUMNS = ("scene", "camera", "f_number", "scene_preset", "seed", "encoding", "method_preset", "estimator")
#: Columns after the inputs and parameters: identity and backend.
INFO_COLUMNS = ("method_variant", "mitsuba_variant")
#: Default metric of the plot and the summary.
DEFAULT_METRIC = "dense_textured_mae"
#: Column value for the scene's own camera (``--camera`` not given).
SCENE_CAMERA = "scene_default"


@dataclasses.dataclass(frozen=True)
class Render:
    """One distinct render of the grid."""

    scene: str
    camera: str | None
    f_number: float
    scene_preset: str
    seed: int

    @property
    def render_id(self) -> str:
        from defocus_cache import hash_key

        return hash_key(dataclasses.asdict(self))


@dataclasses.dataclass(frozen=True)
class Cell:
    """One cell: a render × method preset × estimator × parameter values × encoding."""

    render: Render
    method_preset: str
    estimator: str
    params: tuple  # ((field, value), ...) in --param order
    encoding: str

    def inputs(self) -> dict:
        """Every input, named as the results columns."""
        r = self.render
        return {"scene": r.scene, "camera": r.camera or SCENE_CAMERA, "f_number": r.f_number,
                "scene_preset": r.scene_preset, "seed": r.seed, "encoding": self.encoding,
                "method_preset": self.method_preset, "estimator": self.estimator, **dict(self.params)}

    @property
    def variant_label(self) -> str:
        """The method variant: preset/estimator plus the swept parameter values."""
        extra = "".join(f" {k}={_fmt_value(v)}" for k, v in self.params)
        return f"{self.method_preset}/{self.estimator}{extra}"


@dataclasses.dataclass(frozen=True)
class Grid:
    """A validated sweep grid (:func:`build_grid`)."""

    cells: tuple
    param_names: tuple
    metric: str
    variant: str | None

    @property
    def renders(self) -> tuple:
        return tuple(dict.fromkeys(c.render for c in self.cells))


def _fmt_value(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _parse_bool(text: str) -> bool:
    t = text.strip().lower()
    if t in ("true", "1", "yes", "on"):
        return True
    if t in ("false", "0", "no", "off"):
        return False
    raise ValueError


def parse_param_value(field: str, type_text: str, text: str):
    """One ``--param`` value parsed as the ``DefocusParams`` field's annotated type.

    Parameters
    ----------
    field : str
        Field name (for the message).
    type_text : str
        The field's annotation, e.g. ``"float"``, ``"float | None"``, ``"int | str"``, ``"bool"``.
    text : str
        The value as written on the command line.

    Raises
    ------
    ValueError
        Naming the field, the value and the allowed type; tuple fields are not sweepable.
    """
    types = [t.strip() for t in type_text.split("|")]
    if any(t.startswith("tuple") for t in types):
        raise ValueError(f"--param {field}: tuple fields cannot be swept; allowed: scalar DefocusParams fields")
    t = text.strip()
    if "None" in types and t.lower() in ("none", "null"):
        return None
    if "bool" in types:
        try:
            return _parse_bool(t)
        except ValueError:
            raise ValueError(f"--param {field}={text!r} is invalid; allowed: true or false") from None
    if "int" in types:
        try:
            return int(t)
        except ValueError:
            pass
    if "float" in types:
        try:
            return float(t)
        except ValueError:
            pass
    if "str" in types and t:
        return t
    allowed = " or ".join({"int": "integer", "float": "number", "None": "none", "str": "text"}.get(x, x) for x in types)
    raise ValueError(f"--param {field}={text!r} is invalid; allowed: {allowed}")


def parse_params(specs) -> list[tuple[str, list]]:
    """``["alpha=0.1,0.5", ...]`` → ``[("alpha", [0.1, 0.5]), ...]`` (types from ``DefocusParams``).

    Raises
    ------
    ValueError
        Bad syntax, unknown or repeated field, ``estimator`` (use ``--estimator``), bad value.
    """
    from method import DefocusParams

    fields = DefocusParams.field_types()
    out: dict[str, list] = {}
    for spec in specs or []:
        name, sep, values = str(spec).partition("=")
        name = name.strip()
        if not sep or not name or not values.strip():
            raise ValueError(f"--param {spec!r} is invalid; allowed: FIELD=V1,V2,... (e.g. alpha=0.1,0.5,1)")
        if name == "estimator":
            raise ValueError("--param estimator=... is invalid; allowed: use --estimator NAME ...")
        if name not in fields:
            raise ValueError(f"--param {name!r} is not a DefocusParams field; allowed: "
                             f"{sorted(n for n, t in fields.items() if not str(t).startswith('tuple') and n != 'estimator')}")
        if name in out:
            raise ValueError(f"--param {name} is given twice; allowed: each field once, values comma-separated")
        parsed = [parse_param_value(name, str(fields[name]), v) for v in values.split(",")]
        out[name] = list(dict.fromkeys(parsed))
    return list(out.items())


def _uniq(xs) -> list:
    return list(dict.fromkeys(xs))


def _check_names(scenes, cameras, presets, estimators, encodings, metric, variant) -> tuple:
    """Every name axis of a grid checked against its registry (one ValueError naming the allowed names).

    Returns scenes, cameras (``[None]``: each scene's own), presets, estimators (``[None]``: each
    preset's own) and encodings, each without repeats, in the order given.
    """
    from experiments.evaluation import ENCODINGS, validate_estimators
    from experiments.evaluation_columns import METRIC_COLUMNS
    from method import PRESETS
    from method.registry import Registry
    from repro._cli import check_scene_names
    from scenes import CAMERA_PRESETS
    from scenes.backend import VARIANT_CANDIDATES

    scenes = check_scene_names(_uniq(scenes))
    cams = [None] if not cameras else Registry("camera", CAMERA_PRESETS).check_all(_uniq(cameras))
    try:
        presets = PRESETS.check_all(_uniq(presets))
    except ValueError as exc:
        hint = " (the render size is --scene-size small|full)" if set(presets) & {"small", "full"} else ""
        raise ValueError(f"{exc}{hint}") from None
    ests = [None] if not estimators else list(validate_estimators(_uniq(estimators)))
    encodings = ENCODINGS.check_all(_uniq(encodings))
    Registry("metric", [c for c in METRIC_COLUMNS if c != "seconds_total"]).check(metric, what="--metric")
    Registry("Mitsuba variant", VARIANT_CANDIDATES).check(variant, what="--variant", optional=True)
    return scenes, cams, presets, ests, encodings


def build_grid(*, scenes, cameras=None, f_numbers=(8.0, 4.0), estimators=None, presets=("paper",), params=(),
               seeds=(0,), scene_preset="small", encodings=("srgb",), metric=DEFAULT_METRIC,
               variant=None) -> Grid:
    """Validate every axis of a sweep and enumerate its cells (nothing is rendered or submitted).

    Parameters
    ----------
    scenes : sequence of str, keyword-only
        Keys of :data:`scenes.SCENES`.
    cameras : sequence of str or None, keyword-only
        :data:`scenes.CAMERA_PRESETS` names; None: each scene's own camera.
    f_numbers : sequence of float, keyword-only
        Apertures N (> 0).
    estimators : sequence of str or None, keyword-only
        Keys of :data:`method.BLUR_ESTIMATORS`; None: each preset's own estimator.
    presets : sequence of str, keyword-only
        Keys of :data:`method.PRESETS`.
    params : sequence of (str, list), keyword-only
        Swept ``DefocusParams`` fields and their values (:func:`parse_params`).
    seeds : sequence of int, keyword-only
        Render sampler seeds, in [0, 2**32).
    scene_preset : {"small", "full"}, keyword-only
    encodings : sequence of {"srgb", "linear"}, keyword-only
    metric : str, keyword-only
        Metric column of the plot and summary (:data:`experiments.evaluation_columns.METRIC_COLUMNS`).
    variant : str or None, keyword-only
        Mitsuba variant requested (None: each worker's fastest).

    Returns
    -------
    Grid

    Raises
    ------
    ValueError
        Naming the bad value and what is allowed; every parameter combination is validated by
        building its ``DefocusParams`` (so cross-field rules are checked too).
    """
    from experiments.sweep_cells import cell_params, render_camera
    from scenes.render import validate_render_options

    scenes, cams, presets, ests, encodings = _check_names(scenes, cameras, presets, estimators, encodings,
                                                          metric, variant)
    f_numbers = _uniq(float(n) for n in f_numbers)
    seeds = _uniq(seeds)
    renders = []
    for s, c, n, sd in itertools.product(scenes, cams, f_numbers, seeds):
        validate_render_options(s, render_camera(s, scene_preset=scene_preset, f_number=n, camera=c),
                                preset=scene_preset, f_number=n, seed=sd)  # ValueError on a bad N, seed, preset
        renders.append(Render(scene=s, camera=c, f_number=n, scene_preset=scene_preset, seed=int(sd)))
    names = tuple(name for name, _ in params)
    combos = list(itertools.product(*(vals for _, vals in params))) or [()]
    methods = []
    for p, e, combo in itertools.product(presets, ests, combos):
        changes = dict(zip(names, combo))
        try:
            full = cell_params(p, e, changes)
        except (ValueError, TypeError) as exc:
            shown_changes = ", ".join(f"{k}={v!r}" for k, v in changes.items()) or "no change"
            raise ValueError(f"preset {p!r} with {shown_changes}: {exc}") from None
        methods.append((p, full.estimator, tuple(zip(names, combo))))
    cells = tuple(Cell(render=r, method_preset=p, estimator=e, params=pc, encoding=enc)
                  for r in renders for p, e, pc in methods for enc in encodings)
    return Grid(cells=cells, param_names=names, metric=metric, variant=variant)
