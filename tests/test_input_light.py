"""The input's light declared once: ``estimate_defocus_map(image, params, encoding=...)``.

An image is given in its encoding ("srgb" display values or "linear" radiance, :data:`method.luma.ENCODINGS`)
and converted once into the light each stage measures in (``params.measure_light``: "display" or
"linear", :data:`method.luma.LIGHTS`); the guide of Eq. (3) and Eq. (4) is always display values. So a
linear image and its sRGB encoding give the same maps, for every preset; the same names mean the same
light in method, scenes, the harness and the CLIs.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from method import PRESETS, DefocusParams, estimate_defocus_map
from method.luma import ENCODINGS, LIGHTS, MEASURE_LIGHTS, luminance, measure_input, measure_luminance, to_light
from tests.tolerances import LIGHT_ENCODING_MAP_ATOL_PX


@pytest.fixture(scope="module")
def mosaic():
    """(linear radiance, its sRGB encoding): a 64×64 dead-leaves lens mosaic, σ 0.5–5 px, float (unquantised)."""
    from scenes.analytic.lens import lens_mosaic
    from scenes.display import linear_to_srgb

    m = lens_mosaic(family="dead_leaves", sigmas=(0.5, 1.5, 3.0, 5.0), tile=32, cols=2, quantize_bits=None, rng=3)
    return m.linear, linear_to_srgb(m.linear)


def _run(image, preset, encoding, **changes):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimate_defocus_map(image, DefocusParams.preset(preset, **changes), encoding=encoding)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_linear_input_and_its_srgb_encoding_give_the_same_map(mosaic, preset):
    """Every preset: the maps of the linear image (declared "linear") and of its sRGB encoding agree
    within LIGHT_ENCODING_MAP_ATOL_PX; declaring the linear image "srgb" (what the harness used to do)
    moves the dense map by far more, so the comparison can fail."""
    linear, srgb = mosaic
    a, b = _run(linear, preset, "linear"), _run(srgb, preset, "srgb")
    np.testing.assert_array_equal(a.edges, b.edges)
    for field in ("sparse_sigma", "refined_sigma", "defocus_map"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), atol=LIGHT_ENCODING_MAP_ATOL_PX, rtol=0,
                                   err_msg=f"{preset} {field}")
    wrong = _run(linear, preset, "srgb")
    assert float(np.max(np.abs(wrong.defocus_map - b.defocus_map))) > 100 * LIGHT_ENCODING_MAP_ATOL_PX + 0.1


def test_linear_input_is_not_decoded_twice(mosaic):
    """Linear light of a linear image is the image itself: 0.2 stays 0.2 (decoding it again read it as
    0.033); robust (measure_light "linear") finds the same edge pixels on a linear input as on its sRGB
    encoding (measured 427 both; 228 when the linear input was decoded a second time, with the constant
    noise of Eq. 9: the per-pixel noise model follows the darker image's noise, 732 against 760)."""
    flat = np.full((8, 8, 3), 0.2)
    assert np.array_equal(measure_luminance(flat, "linear", encoding="linear"), np.full((8, 8), 0.2))
    assert measure_luminance(flat, "linear", encoding="srgb")[0, 0] == pytest.approx(0.0331, abs=1e-4)
    linear, srgb = mosaic
    robust = DefocusParams.preset("robust")
    assert robust.measure_light == "linear"
    seen = measure_input(linear, robust, encoding="linear").seen
    np.testing.assert_array_equal(seen, luminance(linear))
    np.testing.assert_allclose(measure_input(srgb, robust, encoding="srgb").seen, seen, atol=1e-12, rtol=0)
    assert int(_run(linear, "robust", "linear").edges.sum()) == int(_run(srgb, "robust", "srgb").edges.sum())
    assert (int(_run(linear, "robust", "srgb", noise_model="constant").edges.sum())
            < 0.8 * int(_run(srgb, "robust", "srgb", noise_model="constant").edges.sum()))


def test_guide_and_display_measures_are_display_values(mosaic):
    """The reference image of Eq. (3)/(4) and the paper's luminance are sRGB values, whatever the encoding."""
    linear, srgb = mosaic
    paper = DefocusParams()
    m = measure_input(linear, paper, encoding="linear")
    np.testing.assert_allclose(m.rgb, srgb, atol=1e-12, rtol=0)
    np.testing.assert_allclose(m.seen, luminance(srgb), atol=1e-12, rtol=0)
    np.testing.assert_array_equal(m.gray, m.seen)
    s = measure_input(srgb, paper)  # default encoding: srgb, used as given
    np.testing.assert_array_equal(s.rgb, srgb)
    grey = measure_input(srgb[..., 1], paper)
    assert grey.rgb.shape == srgb.shape and np.array_equal(grey.gray, srgb[..., 1])


def test_to_light_converts_at_most_once():
    x = np.linspace(0.0, 1.0, 11)
    np.testing.assert_array_equal(to_light(x, "display", encoding="srgb"), x)
    np.testing.assert_array_equal(to_light(x, "linear", encoding="linear"), x)
    np.testing.assert_allclose(to_light(to_light(x, "linear", encoding="srgb"), "display", encoding="linear"), x,
                               atol=1e-12)
    assert to_light(x, "linear", encoding="srgb")[2] == pytest.approx(0.0331, abs=1e-4)


@pytest.mark.parametrize("call", [
    lambda img: estimate_defocus_map(img, encoding="bogus"),
    lambda img: measure_luminance(img, "linear", encoding="bogus"),
    lambda img: to_light(img, "display", encoding="bogus"),
    lambda img: __import__("experiments.evaluation", fromlist=["x"]).sparse_estimates(img, ["model_fit"],
                                                                                       encoding="bogus"),
    lambda img: __import__("method").magnify_defocus(img, np.ones(img.shape[:2]), encoding="bogus"),
])
def test_unknown_encoding_is_a_value_error_naming_the_allowed(call):
    img = np.random.default_rng(0).random((16, 16, 3))
    with pytest.raises(ValueError, match=r"encoding='bogus' is invalid .*allowed: .*'filmic', .*'linear', 'srgb'"):
        call(img)


def test_unknown_light_is_a_value_error():
    with pytest.raises(ValueError, match=r"light='srgb' is invalid .*allowed: 'display', 'linear'"):
        to_light(np.zeros(3), "srgb")
    with pytest.raises(ValueError, match=r"measure_light='srgb' is invalid"):
        DefocusParams(measure_light="srgb")


def test_one_vocabulary_for_encodings_and_lights():
    """method owns the registries; scenes (which may not import method) keeps a tuple of the same
    names, the harness re-exports method's, and every 'light' option uses LIGHTS's names."""
    import inspect

    import experiments.evaluation
    import scenes.display
    from scenes.analytic import lens

    assert tuple(ENCODINGS) == scenes.display.ENCODINGS == ("srgb", "linear", "gamma1.8", "gamma2.2", "filmic")
    assert experiments.evaluation.ENCODINGS is ENCODINGS
    assert MEASURE_LIGHTS is LIGHTS and tuple(LIGHTS) == ("display", "linear")
    assert {ENCODINGS[e] for e in ENCODINGS} == set(LIGHTS)  # each encoding is in one light
    for light in LIGHTS:
        lens._check_light(light)
    assert "light" in inspect.signature(__import__("method").magnify_defocus).parameters


def test_magnifier_blends_in_the_declared_light(mosaic):
    """A linear image blended in linear light equals its sRGB encoding blended in linear light (up to
    the sRGB round trip), so the magnifier reads the same light whatever the input's encoding."""
    from method import magnify_defocus
    from scenes.display import linear_to_srgb

    linear, srgb = mosaic
    sigma = np.full(linear.shape[:2], 1.5)
    for renderer in ("gather", "scatter"):
        a = magnify_defocus(linear, sigma, factor=2.0, renderer=renderer, encoding="linear", light="linear",
                            preprocess=False)
        b = magnify_defocus(srgb, sigma, factor=2.0, renderer=renderer, encoding="srgb", light="linear",
                            preprocess=False)
        np.testing.assert_allclose(linear_to_srgb(a), b, atol=1e-6, err_msg=renderer)
        c = magnify_defocus(srgb, sigma, factor=2.0, renderer=renderer, light="display", preprocess=False)
        assert float(np.max(np.abs(c - b))) > 0.01


# ------------------------------------------------------------------------------------------------
# photo tools: the reader declares the encoding, --encoding overrides it
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(d))
    return d


def test_exr_photo_is_estimated_in_its_linear_light(tmp_path, cache_dir, capsys):
    """repro.estimate on an OpenEXR (linear) photo gives the map of the linear image declared linear
    (= the map of its sRGB encoding); ``--encoding srgb`` (the values taken as display values) gives
    another map, the one of the same values declared "srgb"."""
    from repro.estimate import PROG, main
    from repro.photo_io import read_photo, write_photo
    from tests.photo_cli import cli_runner, textured_photo

    run, _ = cli_runner(main, PROG)
    exr = write_photo(tmp_path / "p.exr", textured_photo(48, 64))  # sRGB image, stored as linear light
    photo = read_photo(exr)
    assert photo.encoding == "linear"
    status, _, _ = run([exr, "-o", tmp_path / "m.npy", "--preset", "robust"], capsys)
    assert status == 0
    expected = _run(photo.image, "robust", "linear").defocus_map
    np.testing.assert_allclose(np.load(tmp_path / "m.npy"), expected, atol=LIGHT_ENCODING_MAP_ATOL_PX, rtol=0)
    status, _, _ = run([exr, "-o", tmp_path / "s.npy", "--preset", "robust", "--encoding", "srgb"], capsys)
    assert status == 0
    assert float(np.max(np.abs(np.load(tmp_path / "s.npy") - expected))) > 0.1
    np.testing.assert_allclose(np.load(tmp_path / "s.npy"), _run(photo.image, "robust", "srgb").defocus_map,
                               atol=LIGHT_ENCODING_MAP_ATOL_PX, rtol=0)


def test_map_cache_key_holds_the_encoding(tmp_path):
    import dataclasses

    from repro._photo_map import map_cache_key
    from repro.photo_io import read_photo, write_photo
    from tests.photo_cli import textured_photo

    photo = read_photo(write_photo(tmp_path / "p.png", textured_photo(16, 16)))
    params = DefocusParams()
    assert map_cache_key(photo, params, (16, 16)) != map_cache_key(dataclasses.replace(photo, encoding="linear"),
                                                                   params, (16, 16))


@pytest.mark.parametrize("module", ["repro.estimate", "repro.magnify"])
def test_cli_unknown_encoding_is_one_line_exit_2(module, tmp_path, cache_dir, capsys):
    import importlib

    from repro.photo_io import write_photo
    from tests.photo_cli import cli_runner, textured_photo

    mod = importlib.import_module(module)
    run, assert_one_line_error = cli_runner(mod.main, mod.PROG)
    photo = write_photo(tmp_path / "p.png", textured_photo(16, 16))
    status, _, err = run([photo, "--encoding", "bogus"], capsys)
    assert_one_line_error(status, err, "--encoding", "bogus", "srgb", "linear")


def test_cli_help_names_the_encoding_default(capsys):
    from repro.estimate import _parser

    text = " ".join(_parser().format_help().split())
    assert "--encoding NAME" in text and "Default: from the file type, linear for OpenEXR" in text
    for name in ("auto", "srgb", "linear", "gamma1.8", "gamma2.2", "filmic"):  # the choices read the registry
        assert f"{name} (" in text
