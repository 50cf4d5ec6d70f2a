"""Parameters per stage: each stage's dataclass validates its own fields; DefocusParams composes them,
checks the rules across stages and keeps the flat interface every caller uses (``DefocusParams(**flat)``,
``params.alpha``, ``replace``, ``changes_from``, ``dataclasses.fields`` / ``asdict`` / ``replace``, cache keys).
"""

import copy
import dataclasses
import json
import pickle

import numpy as np
import pytest

from method import PRESETS, DefocusParams
from method.blur import BlurParams, RegionParams
from method.edges import EdgeParams
from method.magnify import MagnifyParams
from method.propagation import FusionParams, PropagationParams
from method.refine import RefineParams

#: The paper preset's every field as the one flat dataclass held it before the parameters were split by
#: stage (read from that code): the composition must give exactly these values, of these types.
PAPER_BEFORE_THE_SPLIT = {
    # edges (Sec. 3.1)
    "sigma1_scales": (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0), "sigma2_scales": (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0),
    "noise_std": 2.5 / 255.0, "noise_model": "constant", "noise_spectrum": "white", "noise_a": None, "noise_b": None,
    "measure_light": "display", "false_positive_rate": 1e-06, "edge_detector": "elder_zucker",
    "canny_sigma": 1.0, "canny_low_threshold": 0.1, "canny_high_threshold": 0.2, "edge_isolation": None,
    "isolation_radius": 3.0, "isolation_floor": 0.1,
    # blur at edges (Sec. 3.2)
    "estimator": "model_fit", "fit_window_min": 3, "fit_window_max": 71, "max_sigma": 64.0, "fit_max_residual": 0.05,
    "fit_residual_noise": 0.0, "relaxed_fit_weight": 1.0, "measure_weighting": "hand", "fit_scale_ratio": 1.0, "fit_max_scale": None, "fit_follow_scale": None,
    "fit_follow_max_residual": 1.0,
    "fit_min_samples": 3, "fit_max_width_ratio": float("inf"), "fit_below_scale": "zero", "fit_psf": "gaussian",
    "fit_step_gate": "none", "fit_plateau_reach": 0.5,
    "ratio_gradient_sigma": 0.5, "ratio_reblur_sigma": 1.0, "ratio_max_sigma": None, "ratio_zero_is_measure": True,
    # region
    "region_estimator": None, "region_psf": "gaussian", "region_gate": "none", "region_noise_model": "white",
    "region_window_min": 16, "region_window_max": 96, "region_window_scale": 12.0, "region_sigma_min": 0.0,
    "region_sigma_max": 12.0, "region_stride": 32,
    # Eq. (3)
    "refine": True, "bilateral_sigma_spatial": 0.1, "bilateral_sigma_range": 0.1, "sharpness_bias": True,
    "bias_scale": 2.0, "bilateral_method": "grid", "bilateral_range_kernel": "sum", "bias_reference": "px",
    "bias_weighting": "uniform", "refinement_robust_iterations": 0, "refinement_robust_scale": 0.5,
    # fusion
    "fusion_edge_error_rel": 0.5, "fusion_region_error_rel": 0.3, "fusion_region_weight": 1.0,
    "fusion_region_placement": "centres", "fusion_island_weight": 1.0, "fusion_island_radius": 24.0,
    "fusion_straddle_weight": 1.0,
    # Eq. (4)
    "propagation": "colorization", "alpha_confidence": "none", "matting_lambda": 0.005, "matting_epsilon": 1e-05,
    "matting_data_weight": "constant", "matting_tol": 1e-06, "matting_step_tol": None, "alpha": 0.5, "propagation_window": 7,
    "propagation_neighborhood": 3,
    "propagation_tol": 1e-06, "propagation_solver": "amg_pcg", "propagation_downsample": "auto",
    "propagation_refinement": "galerkin",
    # Sec. 5
    "map_clip_percent": 5.0, "map_smoothing": 0.005, "map_floor": "clamp",
    "magnify_renderer": "gather",
}

STAGE_CLASSES = {"edges": EdgeParams, "blur": BlurParams, "region": RegionParams, "refinement": RefineParams,
                 "fusion": FusionParams, "interpolation": PropagationParams, "magnification": MagnifyParams}


def _flat(p):
    return {name: getattr(p, name) for name in DefocusParams.field_types()}


# --- each stage validates its own fields ------------------------------------------------------------

#: One bad value per stage and the allowed range its message must name.
BAD_PER_STAGE = [
    (EdgeParams, "noise_std", 0.0, "> 0"),
    (EdgeParams, "sigma2_scales", (1.0, -2.0), "non-empty tuple of positive scales (px)"),
    (BlurParams, "fit_min_samples", 2, "integer >= 3"),
    (RegionParams, "region_stride", 0, "integer >= 1 (px)"),
    (RefineParams, "bilateral_sigma_spatial", -0.1, "> 0"),
    (FusionParams, "fusion_island_weight", 1.5, "0 <= factor <= 1 (1: off; 0: island measures dropped)"),
    (PropagationParams, "propagation_window", 4, "odd integer >= 3"),
    (MagnifyParams, "map_clip_percent", 50.0, "0 <= p < 50"),
]


@pytest.mark.parametrize("cls, field, value, allowed", BAD_PER_STAGE, ids=lambda v: getattr(v, "__name__", None))
def test_each_stage_refuses_a_bad_value_naming_the_allowed_range(cls, field, value, allowed):
    assert cls() == cls(**{field: getattr(cls(), field)})  # its default is valid
    message = f"DefocusParams.{field}={value!r} is invalid; allowed: {allowed}"
    with pytest.raises(ValueError) as info:
        cls(**{field: value})
    assert str(info.value) == message
    with pytest.raises(ValueError) as info:  # the same message through the composition
        DefocusParams(**{field: value})
    assert str(info.value) == message


@pytest.mark.parametrize("cls, field, registry_names", [
    (EdgeParams, "edge_detector", ("canny", "elder_zucker")),
    (BlurParams, "fit_psf", ("auto", "best", "disk", "gaussian")),
    (BlurParams, "fit_step_gate", ("none", "plateau", "plateau_flat")),
    (RegionParams, "region_gate", ("adequacy", "none")),
    (RefineParams, "bias_reference", ("image_fraction", "px")),
    (BlurParams, "measure_weighting", ("hand",)),
    (FusionParams, "fusion_region_placement", ("blocks", "centres")),
    (PropagationParams, "alpha_confidence", ("agreement", "none")),
    (MagnifyParams, "map_floor", ("clamp", "shift", "subtract")),
])
def test_each_stage_reads_its_registries(cls, field, registry_names):
    for name in registry_names:
        assert getattr(cls(**{field: name}), field) == name
    with pytest.raises(ValueError, match=rf"DefocusParams\.{field}='nope' is invalid") as info:
        cls(**{field: "nope"})
    assert all(repr(n) in str(info.value) for n in registry_names)


def test_stage_classes_are_frozen_and_keyword_only():
    for cls in STAGE_CLASSES.values():
        obj = cls()
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, dataclasses.fields(cls)[0].name, None)
        with pytest.raises(TypeError):
            cls(dataclasses.fields(cls)[0].default)


def test_the_scales_are_normalised_by_the_edge_stage():
    assert EdgeParams(sigma1_scales=[2, 0.5, 1]).sigma1_scales == (0.5, 1.0, 2.0)
    assert DefocusParams(sigma2_scales=(4, 1)).sigma2_scales == (1.0, 4.0)


# --- the rules across stages --------------------------------------------------------------------------

def test_canny_edges_need_the_gradient_ratio_estimator():
    assert EdgeParams(edge_detector="canny").edge_detector == "canny"  # valid for the edge stage alone
    with pytest.raises(ValueError, match=r"DefocusParams\.edge_detector='canny' is invalid; allowed: 'canny' only "
                                         r"with estimator='gradient_ratio'"):
        DefocusParams(edge_detector="canny")
    assert DefocusParams(edge_detector="canny", estimator="gradient_ratio").edge_detector == "canny"
    with pytest.raises(ValueError, match="edge_detector='canny'"):
        DefocusParams.preset("zhuo_sim").replace(estimator="model_fit")


def test_region_measures_need_the_colorization_propagation():
    assert PropagationParams(propagation="matting_laplacian").propagation == "matting_laplacian"
    assert RegionParams(region_estimator="gsm").region_estimator == "gsm"
    with pytest.raises(ValueError, match=r"DefocusParams\.propagation='matting_laplacian' is invalid; allowed: "
                                         r"'colorization' when region_estimator is set"):
        DefocusParams(region_estimator="gsm", propagation="matting_laplacian")
    assert DefocusParams(region_estimator="gsm").propagation == "colorization"
    assert DefocusParams(propagation="matting_laplacian").region_estimator is None


# --- the composition is the flat parameter set it replaced --------------------------------------------

def test_paper_preset_has_every_value_of_the_flat_class():
    got = _flat(DefocusParams())
    assert list(got) == list(PAPER_BEFORE_THE_SPLIT)  # every field, in pipeline order
    assert {k: (type(v), v) for k, v in got.items()} == {k: (type(v), v) for k, v in PAPER_BEFORE_THE_SPLIT.items()}
    # the probe fails on a changed default
    assert _flat(DefocusParams(region_stride=16)) != PAPER_BEFORE_THE_SPLIT


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_flat_field_reads_its_stage(name):
    p = PRESETS[name]
    stages = p.stages()
    assert list(stages) == list(STAGE_CLASSES)
    assert all(type(stages[s]) is cls and getattr(p, s) is stages[s] for s, cls in STAGE_CLASSES.items())
    for field in DefocusParams.field_types():
        stage = DefocusParams.stage_of(field)
        assert getattr(p, field) == getattr(stages[stage], field)
    # rebuilt from its stages, from its flat fields and by dataclasses.replace: the same value
    assert DefocusParams(**stages) == p == DefocusParams(**_flat(p)) == dataclasses.replace(p)
    assert hash(DefocusParams(**_flat(p))) == hash(p)


def test_field_names_are_one_namespace():
    names = [f.name for cls in STAGE_CLASSES.values() for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names)) == len(DefocusParams.field_types()) == 84
    assert not set(names) & set(STAGE_CLASSES)
    assert DefocusParams.stage_classes() == STAGE_CLASSES
    with pytest.raises(ValueError, match="'nope' is invalid"):
        DefocusParams.stage_of("nope")


def test_field_types_list_what_the_sweep_parses():
    types = DefocusParams.field_types()
    assert list(types) == [f.name for f in dataclasses.fields(DefocusParams)]
    assert types["alpha"] == "float" and types["propagation_downsample"] == "int | str"
    assert types["sigma1_scales"] == "tuple[float, ...]" and types["ratio_max_sigma"] == "float | None"
    assert types["refine"] == "bool" and types["region_stride"] == "int"


def test_replace_changes_flat_fields_and_whole_stages():
    p = DefocusParams()
    q = p.replace(alpha=0.25, noise_std=0.02)
    assert (q.alpha, q.noise_std, p.alpha) == (0.25, 0.02, 0.5)
    assert q.changes_from(p) == {"alpha": (0.25, 0.5), "noise_std": (0.02, 2.5 / 255)}
    assert q.blur is p.blur and q.refinement is p.refinement  # untouched stages are shared, not rebuilt
    r = p.replace(interpolation=PropagationParams(alpha=0.75), propagation_window=9)  # a stage, then a field on it
    assert (r.alpha, r.propagation_window) == (0.75, 9)
    assert p.replace() == p
    with pytest.raises(ValueError, match=r"DefocusParams\.edges=.* is invalid; allowed: an instance of EdgeParams"):
        p.replace(edges=BlurParams())
    with pytest.raises(TypeError, match="unexpected keyword argument 'alfa'"):
        p.replace(alfa=0.3)
    with pytest.raises(TypeError, match="unexpected keyword argument 'alfa'"):
        DefocusParams(alfa=0.3)


def test_value_semantics():
    p, q = DefocusParams(), DefocusParams()
    assert p == q and hash(p) == hash(q) and len({p, q, p.replace(alpha=0.3)}) == 2
    assert p != p.replace(alpha=0.3) and p != object()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.alpha = 0.3
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.interpolation = PropagationParams()
    for name in PRESETS:
        assert pickle.loads(pickle.dumps(PRESETS[name])) == PRESETS[name]
        assert copy.deepcopy(PRESETS[name]) == PRESETS[name]
    assert "interpolation=PropagationParams(" in repr(p)


def test_dataclass_protocol_is_flat():
    """dataclasses.fields / asdict / replace / is_dataclass see the flat fields (sweep cells, the photo
    tool's cache key and experiments.cache_keys.to_jsonable rely on it)."""
    p = DefocusParams.preset("robust")
    assert dataclasses.is_dataclass(p) and dataclasses.is_dataclass(DefocusParams)
    assert dataclasses.asdict(p) == _flat(p)
    assert dataclasses.replace(p, alpha=0.3) == p.replace(alpha=0.3)
    assert {f.name for f in dataclasses.fields(p)} == set(PAPER_BEFORE_THE_SPLIT)
    assert {f.name: f.default for f in dataclasses.fields(DefocusParams)} == _flat(DefocusParams())


def test_dask_tokenizes_by_value():
    """Dask's tokenize reads the dataclass protocol (fields and __dataclass_params__): equal parameters,
    equal tokens; a changed field, another token."""
    tokenize = pytest.importorskip("dask.base").tokenize
    p = DefocusParams.preset("robust")
    assert tokenize(p) == tokenize(DefocusParams(**_flat(p))) != tokenize(p.replace(alpha=0.3))


def test_json_cache_key_is_deterministic_and_holds_every_field():
    from defocus_cache import hash_key
    from experiments.cache_keys import to_jsonable

    keys = {}
    for name in PRESETS:
        js = to_jsonable(PRESETS[name])
        assert set(js) == set(DefocusParams.field_types())
        assert json.dumps(js, sort_keys=True) == json.dumps(to_jsonable(DefocusParams.preset(name)), sort_keys=True)
        keys[name] = hash_key(js)
    assert len(set(keys.values())) == len(keys)
    assert hash_key(to_jsonable(PRESETS["paper"].replace(region_stride=16))) != keys["paper"]


# --- stage functions take their stage's parameters -------------------------------------------------

def test_stage_functions_accept_their_stage_parameters():
    from method.pipeline import refine_stage
    from method.propagation import propagate_blur_measures

    rng = np.random.default_rng(0)
    rgb = rng.uniform(0, 1, (24, 24, 3))
    sparse = np.full((24, 24), np.nan)
    sparse[::3, ::3] = rng.uniform(0.5, 3.0, (8, 8))
    p = DefocusParams(bilateral_method="brute_force", propagation_solver="direct")
    np.testing.assert_array_equal(refine_stage(sparse, rgb, params=p.refinement), refine_stage(sparse, rgb, params=p))
    np.testing.assert_array_equal(propagate_blur_measures(sparse, rgb, params=p.interpolation),
                                  propagate_blur_measures(sparse, rgb, params=p))
    # and the stage's values are the ones used
    assert not np.array_equal(propagate_blur_measures(sparse, rgb, params=p.interpolation),
                              propagate_blur_measures(sparse, rgb, params=p.replace(alpha=5.0).interpolation))


# --- the stage modules say what and why; measurements live in docs/ ----------------------------------

def _stage_sources():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "method"
    return sorted(root.glob("*/params.py")) + [root / "params.py"]


def test_every_stage_field_has_a_comment():
    """Each field (or run of fields sharing one) is followed by its comment: what, unit, reference."""
    import ast

    for path in _stage_sources():
        lines = path.read_text(encoding="utf-8").splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            if not (isinstance(node, ast.ClassDef) and node.name.endswith("Params") and node.name != "DefocusParams"):
                continue
            fields = [n for n in node.body if isinstance(n, ast.AnnAssign)]
            ends = [n.lineno for n in node.body if not isinstance(n, ast.AnnAssign) and n.lineno > fields[-1].lineno]
            for i, f in enumerate(fields):
                stop = fields[i + 1].lineno if i + 1 < len(fields) else ends[0]
                gap = [ln.strip() for ln in lines[f.end_lineno:stop - 1] if ln.strip()]
                adjacent = not gap and i + 1 < len(fields)
                assert adjacent or (gap and gap[0].startswith("#")), f"{path.name}: {node.name}.{f.target.id}"


def test_parameter_modules_carry_no_measurement_history():
    import re

    for path in _stage_sources():
        text = path.read_text(encoding="utf-8")
        # a date, an error figure, or a measured change "0.44 → 0.41"
        assert not re.search(r"\b20\d\d-\d\d-\d\d\b|\bMAE\b|\d\s*→\s*\d", text), path
