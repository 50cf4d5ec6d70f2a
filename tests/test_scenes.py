"""Scene registry, renders and their ground truth (scenes/library, scenes/ground_truth.py, scenes/render.py)."""

import math
import os
import subprocess
import sys
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

from scenes.ground_truth import depth_discontinuities, occlusion_boundary_mask
from scenes.camera import PAPER_CAMERAS
from scenes.library import PRESETS, SCENE_SETS, SCENES, SceneDefinition
from scenes.library.base import emissive, facing_rectangle, image_extent
from scenes.render import load_render, render_scene
from scenes.thin_lens import BOX_FILTER_SIGMA_PX
from tolerances import (
    SCENE_DEPTH_ATOL_M,
    SCENE_EMISSION_ATOL,
    SCENE_F4_F8_COC_RATIO_RTOL,
    SCENE_ORIENTATION_MARGIN,
    SCENE_SIGMA_FLOOR_ATOL_PX,
    SCENE_SIGMA_FLOOR_PX,
    SCENE_SMALL_F8_MIN_MAX_SIGMA_PX,
    SCENE_TILTED_DEPTH_RTOL,
)

ROOT = Path(__file__).resolve().parents[1]

#: Largest σ_gt at f/8 of a ``paper_cameras`` scene, px, at the small preset (160 px wide: a quarter of the
#: full preset's blur; the issue's regime is ~4 px at f/8 at 640 px): at least this.
PAPER_SMALL_F8_MIN_MAX_SIGMA_PX = 0.9
#: The issue's target for the paper_cameras set at the full preset: largest σ_gt about 4 px at f/8 and
#: about 8 px at f/4 (px; a band, since "about" is not a number).
PAPER_FULL_MAX_SIGMA_BAND_PX = {8.0: (3.5, 4.5), 4.0: (7.0, 9.0)}


#: patio_table (the path-traced soft-shadow/gloss scene) ends at a wall at 3.2 m and a garden at 9 m:
#: σ_gt ≤ 2.1 px at f/8 at the full preset (0.59 px small); its point is the outliers at the focus.
PATIO_SMALL_F8_MIN_MAX_SIGMA_PX = 0.5


def _small_f8_min_max_sigma(name):
    if name == "patio_table":
        return PATIO_SMALL_F8_MIN_MAX_SIGMA_PX
    return PAPER_SMALL_F8_MIN_MAX_SIGMA_PX if name in SCENE_SETS["paper_cameras"] else SCENE_SMALL_F8_MIN_MAX_SIGMA_PX


# --- registry (no rendering) ---------------------------------------------------------------------
def test_registry_contents():
    assert {"planes", "tilted_plane", "portrait", "clutter", "shadow_gloss"} <= set(SCENES)
    for name, s in SCENES.items():
        assert s.name == name and isinstance(s.version, int) and s.description
        small, full = s.camera("small"), s.camera("full")
        assert small.resolution[0] <= 160 and small.resolution[1] <= 120
        assert full.resolution[0] >= 640 and full.resolution[1] >= 480
        assert small.f_number == 8.0 and s.camera("small", f_number=4.0).f_number == 4.0
        if name in SCENE_SETS["tabletop_stress"]:
            assert small.focal_length_mm == 50.0 and small.sensor_width_mm == 36.0
        else:  # the paper's cameras with their own lenses, focused on the scene's subject
            lens = PAPER_CAMERAS[s.camera_name]
            assert (small.focal_length_mm, small.sensor_width_mm) == (lens.focal_length_mm, lens.sensor_width_mm)
            assert small.focus_distance_m == s.focus_distance_m >= 2.0
        assert s.spp("small") > 0 and s.spp("full") > 0
    assert PRESETS["small"] == (160, 120) and PRESETS["full"] == (640, 480)


def test_scene_camera_rejects_bad_preset():
    with pytest.raises(ValueError, match="preset"):
        SCENES["planes"].camera("huge")


def test_ground_truth_mask_on_synthetic_depth():
    z = np.full((20, 30), 2.0)
    z[:, 15:] = 0.5
    coc = np.where(z > 1, 6.0, 2.0)
    h, v = depth_discontinuities(z)
    assert h[:, 14].all() and h.sum() == 20 and not v.any()
    mask = occlusion_boundary_mask(z, coc)
    # Radius = max CoC / 2 + 1 px = 4 px either side of the edge between columns 14 and 15.
    assert mask[:, 11:19].all() and not mask[:, :10].any() and not mask[:, 20:].any()
    # A plane seen at a grazing angle (1/z affine, big steps) is not a discontinuity.
    rows = np.linspace(0.05, 1.0, 40)[:, None] * np.ones((1, 5))
    assert not occlusion_boundary_mask(1.0 / rows, np.ones_like(rows)).any()


# --- renders ---------------------------------------------------------------------------------------
@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    """A fresh, empty cache for one test (renders, σ ranges), so what it renders or measures is really computed."""
    old = os.environ.get("DEFOCUS_CACHE_DIR")
    d = tmp_path / "render-cache"
    d.mkdir()
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(d))
    # Keep the variant probe results and Dr.Jit kernels of the project cache.
    proj = Path(old) if old else ROOT / ".cache"
    if (proj / "variant-probes.json").exists():
        (d / "variant-probes.json").write_bytes((proj / "variant-probes.json").read_bytes())
    return d


@pytest.fixture(scope="module")
def small_renders():
    """Every scene at the small preset (f/8, its default spp and seed 0) from the session's render cache: the
    renders the quick figures read (content-keyed, so a change of a scene or of the ground-truth code is a
    new entry, rendered here or by the first figure that needs it). test_full_preset_render renders every
    scene without any cache."""
    return {name: render_scene(name, preset="small", progress=False) for name in SCENES}


@pytest.mark.render
@pytest.mark.parametrize("name", sorted(SCENES))
def test_small_render_valid(small_renders, name):
    r = small_renders[name]
    h, w = 120, 160
    assert r.rgb.shape == (h, w, 3) and r.rgb.dtype == np.float32
    assert np.isfinite(r.rgb).all() and r.rgb.min() >= 0 and r.rgb.mean() > 0.02
    for a in (r.depth, r.coc_px, r.sigma_px):
        assert a.shape == (h, w) and a.dtype == np.float32
    assert r.occlusion_boundary.shape == (h, w) and r.occlusion_boundary.dtype == bool
    assert np.isfinite(r.sigma_px).all()
    # σ_gt spans from (near) the box-filter floor to a useful blur.
    assert r.sigma_px.min() >= SCENE_SIGMA_FLOOR_PX - 1e-4
    assert r.sigma_px.min() <= SCENE_SIGMA_FLOOR_PX + 0.2
    assert r.sigma_px.max() >= _small_f8_min_max_sigma(name)
    # Ground truth consistent with Eq. (5) of the recorded camera.
    cam = r.camera
    np.testing.assert_allclose(r.coc_px, cam.coc_px(r.depth.astype(np.float64)), rtol=1e-5, atol=1e-6)


@pytest.mark.render
@pytest.mark.parametrize("name", sorted(SCENES))
def test_exr_reads_back(small_renders, name):
    r = small_renders[name]
    assert r.path is not None and r.path.suffix == ".exr" and r.path.with_suffix(".json").is_file()
    back = load_render(r.path)
    for field in ("rgb", "depth", "coc_px", "sigma_px", "occlusion_boundary"):
        np.testing.assert_array_equal(getattr(back, field), getattr(r, field))
    m = back.metadata
    for k in ("scene", "scene_version", "camera", "resolution", "spp", "seed", "variant", "versions",
              "sigma_convention", "filter_sigma_px", "render_time_s"):
        assert k in m, k
    assert m["scene"] == name and m["resolution"] == [160, 120] and m["sigma_convention"] == "line_spread"
    assert set(m["versions"]) >= {"mitsuba", "drjit", "numpy"}
    assert m["filter_sigma_px"] == pytest.approx(BOX_FILTER_SIGMA_PX)


@pytest.mark.render
def test_planes_depth_is_exact(small_renders):
    r = small_renders["planes"]
    depths = np.array(SCENES["planes"].facts["plane_depths_m"])
    err = np.min(np.abs(r.depth[..., None] - depths), axis=-1)
    assert err.max() <= SCENE_DEPTH_ATOL_M
    # Every plane is visible.
    for z in depths:
        assert (np.abs(r.depth - z) <= SCENE_DEPTH_ATOL_M).sum() > 100, z
    # The in-focus plane (z = D) is at the box-filter floor exactly.
    focus = np.abs(r.depth - SCENES["planes"].focus_distance_m) < 1e-4
    np.testing.assert_allclose(r.sigma_px[focus], SCENE_SIGMA_FLOOR_PX, atol=SCENE_SIGMA_FLOOR_ATOL_PX)
    # Step edges between planes are in the occlusion mask; so is each pixel beside a jump.
    h, v = depth_discontinuities(r.depth)
    assert r.occlusion_boundary[:, :-1][h].all() and r.occlusion_boundary[:-1, :][v].all()
    assert 0.05 < r.occlusion_boundary.mean() < 0.8


@pytest.mark.render
def test_tilted_plane_depth_matches_geometry(small_renders):
    r = small_renders["tilted_plane"]
    fact = SCENES["tilted_plane"].facts["plane"]
    cam = r.camera
    w, h = cam.resolution
    tan_y = math.tan(math.radians(cam.fov_x_deg) / 2) * h / w
    b = (1.0 - 2.0 * (np.arange(h) + 0.5) / h) * tan_y  # ray slope y/z per row (+ = up)
    z_expect = fact["z0_m"] / (1.0 - fact["slope_dz_dy"] * b)
    np.testing.assert_allclose(r.depth, np.broadcast_to(z_expect[:, None], (h, w)), rtol=SCENE_TILTED_DEPTH_RTOL)
    assert r.occlusion_boundary.mean() < 0.01  # continuous depth: no occlusion boundaries


def _plane_scene(texture, *, z=2.0, focus=2.0, box=(-1.5, 1.5, -1.5, 1.5)):
    def shapes():
        ext = image_extent(focus)
        return {"card": emissive(facing_rectangle(z, *box, extent=ext), texture)}

    return SceneDefinition(name=f"test_plane_{z}", version=1, description="test", focus_distance_m=focus,
                           shapes=shapes, default_spp=MappingProxyType({"small": 64, "full": 64}))


@pytest.mark.render
def test_fronto_parallel_plane_at_two_metres(cache_dir):
    tex = np.full((8, 8, 3), 0.5, np.float32)
    s = _plane_scene(tex, z=2.0, focus=1.0)
    r = render_scene(s, s.camera("small", resolution=(64, 48)), progress=False, use_cache=False)
    np.testing.assert_allclose(r.depth, 2.0, atol=SCENE_DEPTH_ATOL_M)
    np.testing.assert_allclose(r.coc_px, r.camera.coc_px(2.0), rtol=1e-4)
    np.testing.assert_allclose(r.rgb, 0.5, atol=1e-5)  # uniform emission, no lighting noise
    assert r.path is None and not r.occlusion_boundary.any()


@pytest.mark.render
def test_texture_orientation_quadrants(cache_dir):
    # Texture array: top-left red, top-right green, bottom-left blue, bottom-right white.
    tex = np.zeros((64, 64, 3), np.float32)
    tex[:32, :32] = [0.8, 0, 0]
    tex[:32, 32:] = [0, 0.8, 0]
    tex[32:, :32] = [0, 0, 0.8]
    tex[32:, 32:] = [0.8, 0.8, 0.8]
    s = _plane_scene(tex, z=0.5, focus=0.5, box=(-0.5, 0.5, -0.5, 0.5))
    r = render_scene(s, s.camera("small", resolution=(80, 60)), progress=False, use_cache=False)
    img = r.rgb
    # Card covers columns 20..60 and rows 15..45; sample the quadrant centres.
    np.testing.assert_allclose(img[22, 30], [0.8, 0, 0], atol=SCENE_EMISSION_ATOL)   # top-left: red
    np.testing.assert_allclose(img[22, 50], [0, 0.8, 0], atol=SCENE_EMISSION_ATOL)   # top-right: green
    np.testing.assert_allclose(img[38, 30], [0, 0, 0.8], atol=SCENE_EMISSION_ATOL)   # bottom-left: blue
    np.testing.assert_allclose(img[38, 50], [0.8] * 3, atol=SCENE_EMISSION_ATOL)     # bottom-right: white
    assert np.isinf(r.depth[2, 2]) and img[2, 2].max() == 0  # outside the card: a miss
    # The card's border is an occlusion boundary (card vs miss), its centre is not.
    assert r.occlusion_boundary[30, 20] and not r.occlusion_boundary[30, 40]


@pytest.mark.render
def test_world_plus_x_is_image_left(cache_dir):
    # RENDERING-FACTS: with the camera at the origin looking down +z, world +x appears on the left.
    tex = np.full((4, 4, 3), 0.7, np.float32)

    def shapes():
        import mitsuba as mi

        T = mi.ScalarTransform4f
        rect = {"type": "rectangle", "to_world": T().translate([0.1, 0.0, 1.0]) @ T().rotate([0, 1, 0], 180)
                @ T().scale([0.05, 0.05, 1.0])}
        return {"card": emissive(rect, tex)}

    s = SceneDefinition(name="test_plus_x", version=1, description="test", focus_distance_m=1.0, shapes=shapes)
    r = render_scene(s, s.camera("small", resolution=(64, 48)), spp=16, progress=False, use_cache=False)
    cols = np.nonzero(np.isfinite(r.depth).any(axis=0))[0]
    assert cols.max() < 32  # entirely in the left half


@pytest.mark.render
def test_planes_texture_upright(small_renders):
    from scenes.library import textures

    r = small_renders["planes"]
    name, (u0, u1, v0, v1) = SCENES["planes"].facts["upright_texture"]
    tex = textures.photo(name).mean(axis=2)
    h, w = r.depth.shape
    ys, xs = np.mgrid[0:h, 0:w]
    u = 2 * (xs + 0.5) / w - 1
    v = 1 - 2 * (ys + 0.5) / h
    sel = np.abs(r.depth - SCENES["planes"].focus_distance_m) < 1e-4
    sel &= ~r.occlusion_boundary
    fu = (u[sel] - u0) / (u1 - u0)  # texture column fraction, 0 = left
    fv = (v1 - v[sel]) / (v1 - v0)  # texture row fraction, 0 = top
    th, tw = tex.shape
    img = r.rgb.mean(axis=2)[sel]

    def corr(rows, cols):
        t = tex[np.clip((rows * th).astype(int), 0, th - 1), np.clip((cols * tw).astype(int), 0, tw - 1)]
        return np.corrcoef(t, img)[0, 1]

    upright = corr(fv, fu)
    assert upright > 0.8
    assert upright > corr(1 - fv, fu) + SCENE_ORIENTATION_MARGIN  # upside down
    assert upright > corr(fv, 1 - fu) + SCENE_ORIENTATION_MARGIN  # mirrored


@pytest.mark.render
def test_f4_doubles_the_coc_and_convention_switch(small_renders):
    r8 = small_renders["planes"]
    r4 = render_scene("planes", preset="small", f_number=4.0, progress=False)
    np.testing.assert_array_equal(r4.depth, r8.depth)
    pos = r8.coc_px > 0.5
    np.testing.assert_allclose(r4.coc_px[pos] / r8.coc_px[pos], 2.0, rtol=SCENE_F4_F8_COC_RATIO_RTOL)
    assert r4.sigma_px.max() > 1.9 * r8.sigma_px.max() - 0.1
    assert r4.path != r8.path
    re = render_scene("planes", preset="small", sigma_convention="erf_fit", progress=False)
    np.testing.assert_allclose(re.sigma_px, np.sqrt((0.273 * re.coc_px.astype(np.float64)) ** 2 + 1 / 12), rtol=1e-5)
    assert re.metadata["sigma_convention"] == "erf_fit"


@pytest.mark.render
def test_render_image_encodings(small_renders):
    r = small_renders["portrait"]
    img = r.image()
    assert img.shape == (120, 160, 3) and img.min() >= 0 and img.max() <= 1
    q = r.image(quantize_bits=8)
    np.testing.assert_allclose(q * 255, np.round(q * 255), atol=1e-9)
    lin = r.image(encoding="linear", exposure=2.0)
    np.testing.assert_allclose(lin, np.clip(r.rgb.astype(np.float64) * 2, 0, 1))


@pytest.mark.render
def test_cache_hit_and_truncated_entry_rebuilt(cache_dir):
    # a cheap render in a cache of this test's own (the entry is truncated below)
    r = render_scene("tilted_plane", preset="small", spp=16, progress=False)
    assert Path(r.path).is_relative_to(cache_dir)
    import scenes.render as render_module

    def no_render(*args, **kwargs):
        raise AssertionError("a cached render was rendered again")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(render_module, "_compute", no_render)
        again = render_scene("tilted_plane", preset="small", spp=16, progress=False)
    assert again.path == r.path
    np.testing.assert_array_equal(again.rgb, r.rgb)
    with open(r.path, "r+b") as fh:
        fh.truncate(r.path.stat().st_size // 2)
    rebuilt = render_scene("tilted_plane", preset="small", spp=16, progress=False)
    np.testing.assert_array_equal(rebuilt.rgb, r.rgb)  # same seed: bit-identical
    np.testing.assert_array_equal(rebuilt.sigma_px, r.sigma_px)


_RENDER_WORKER = """
import sys
sys.path.insert(0, sys.argv[1])
from scenes.render import render_scene
r = render_scene("planes", preset="small", spp=8, seed=7, progress=False)
print(r.path)
"""


@pytest.mark.render
def test_two_processes_render_one_entry(cache_dir):
    env = dict(os.environ, DEFOCUS_CACHE_DIR=str(cache_dir))
    procs = [subprocess.Popen([sys.executable, "-c", _RENDER_WORKER, str(ROOT)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]
    paths = {out.strip().splitlines()[-1] for out, _ in outs}
    assert len(paths) == 1
    r = load_render(paths.pop())
    assert r.metadata["spp"] == 8 and r.metadata["seed"] == 7


@pytest.mark.render
def test_render_scene_rejects_bad_options():
    with pytest.raises(ValueError, match="unknown scene"):
        render_scene("nope")
    with pytest.raises(ValueError, match="spp"):
        render_scene("planes", spp=0)
    with pytest.raises(ValueError, match="f_number"):
        render_scene("planes", f_number=-1.0)
    with pytest.raises(ValueError, match="sigma_convention"):
        render_scene("planes", sigma_convention="fwhm")
    with pytest.raises(ValueError, match="preset"):
        render_scene("planes", preset="medium")


@pytest.mark.render
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SCENES))
def test_full_preset_render(name, cache_dir):
    # Rendered without any cache. 4 spp: the assertions read the shape, finiteness and σ_gt (from lens-centre
    # rays, independent of spp); the default spp only lowers noise.
    r = render_scene(name, preset="full", spp=4, progress=False, use_cache=False)
    assert r.rgb.shape == (480, 640, 3) and np.isfinite(r.rgb).all()
    assert r.sigma_px.min() <= SCENE_SIGMA_FLOOR_PX + 0.5
    assert r.sigma_px.max() >= 4 * _small_f8_min_max_sigma(name)


def test_spp_chunks_sum_and_are_sampler_friendly():
    from scenes.render import _chunks, _sampler_accepts

    for spp in (1, 7, 32, 128, 256, 512, 1000):
        for pixels in (100, 19200, 307200):
            c = _chunks(spp, pixels)
            assert sum(c) == spp and all(k > 0 and _sampler_accepts(k) for k in c)


@pytest.mark.render
def test_sampler_rounding_rule_matches_mitsuba():
    from scenes.backend import import_mitsuba
    from scenes.library.base import SAMPLER
    from scenes.render import _sampler_accepts

    mi, _ = import_mitsuba()
    for n in range(1, 300):
        if _sampler_accepts(n):
            assert mi.load_dict({"type": SAMPLER, "sample_count": n}).sample_count() == n, n


# --- scene sets and the paper's regime --------------------------------------------------------------
def test_scene_sets_partition_the_scenes():
    import scenes

    assert set(SCENE_SETS) == {"paper_cameras", "tabletop_stress"} and scenes.SCENE_SETS is SCENE_SETS
    paper, stress = set(SCENE_SETS["paper_cameras"]), set(SCENE_SETS["tabletop_stress"])
    assert not paper & stress and paper | stress == set(SCENES)
    assert stress == {"planes", "tilted_plane", "portrait", "clutter", "shadow_gloss"}
    assert scenes.get_scene_set("paper_cameras") == SCENE_SETS["paper_cameras"]
    with pytest.raises(ValueError, match="scene set"):
        scenes.get_scene_set("nope")


def test_paper_cameras_are_the_papers():
    """Sec. 6: Canon 1D Mark II 28.7x19.1 mm + 85 mm; PowerShot A80 7.18x5.32 mm, 7.8 mm, f/2.8; Nikon D50
    23.7x15.6 mm + 180 mm, f/4.8."""
    c = PAPER_CAMERAS
    assert (c["canon_1d_mark_ii_85mm"].sensor_width_mm, c["canon_1d_mark_ii_85mm"].sensor_height_mm,
            c["canon_1d_mark_ii_85mm"].focal_length_mm) == (28.7, 19.1, 85.0)
    assert (c["powershot_a80_7_8mm"].sensor_width_mm, c["powershot_a80_7_8mm"].focal_length_mm,
            c["powershot_a80_7_8mm"].f_number) == (7.18, 7.8, 2.8)
    assert (c["nikon_d50_180mm"].sensor_width_mm, c["nikon_d50_180mm"].sensor_height_mm,
            c["nikon_d50_180mm"].focal_length_mm, c["nikon_d50_180mm"].f_number) == (23.7, 15.6, 180.0, 4.8)
    # the 85 mm portrait lens on the 1D Mark II: about 18° horizontally, not the 50 mm presets' 38°
    assert 17.5 < SCENES["portrait_garden"].camera("full").fov_x_deg < 19.0


@pytest.mark.render
@pytest.mark.slow
def test_paper_cameras_sigma_span_the_papers_regime_at_the_full_preset():
    """Measured on the ground truth (lens-centre-ray depth, Eq. 5): every paper_cameras scene has in-focus
    pixels at the box-filter floor, and its largest σ_gt is about 4 px at f/8 and 8 px at f/4; the tabletop
    stress scenes go far beyond (≥ 10.5 px at f/4; shadow_gloss 11.0 px). The ranges come from the session's
    cache (content-keyed; ``repro.render --list`` reads the same entries)."""
    from scenes.library.ranges import sigma_gt_ranges

    for name in SCENE_SETS["paper_cameras"]:
        r = sigma_gt_ranges(name, presets=("full",))["full"]["f_numbers"]
        for n, (lo, hi) in PAPER_FULL_MAX_SIGMA_BAND_PX.items():
            assert abs(r[f"{n:g}"]["min_px"] - SCENE_SIGMA_FLOOR_PX) < SCENE_SIGMA_FLOOR_ATOL_PX, (name, n)
            if name != "patio_table":  # the path-traced outlier scene: wall at 3.2 m, garden at 9 m
                assert lo <= r[f"{n:g}"]["max_px"] <= hi, (name, n, r[f"{n:g}"])
        assert r["4"]["max_px"] > 1.8 * r["8"]["max_px"]
    stress = [sigma_gt_ranges(n, presets=("full",))["full"]["f_numbers"]["4"]["max_px"]
              for n in SCENE_SETS["tabletop_stress"]]
    assert min(stress) >= 10.5


@pytest.mark.render
def test_sigma_ranges_are_the_renders_ground_truth(small_renders):
    """scenes.library.ranges measures the same σ_gt a render carries (small preset, both apertures)."""
    from scenes.library.ranges import sigma_gt_ranges

    r = sigma_gt_ranges("portrait_garden", presets=("small",))["small"]
    for n in (8.0, 4.0):
        render = render_scene("portrait_garden", preset="small", f_number=n, progress=False)
        got = r["f_numbers"][f"{n:g}"]
        assert got["min_px"] == pytest.approx(float(render.sigma_px.min()), abs=1e-6)
        assert got["max_px"] == pytest.approx(float(render.sigma_px.max()), abs=1e-6)
    assert r["depth_m"][0] == pytest.approx(SCENES["portrait_garden"].facts["foreground_depth_m"], rel=0.01)
    with pytest.raises(ValueError, match="f_numbers"):
        sigma_gt_ranges("portrait_garden", f_numbers=(0.0,))
    with pytest.raises(ValueError, match="preset"):
        sigma_gt_ranges("portrait_garden", presets=("huge",))


@pytest.mark.render
def test_paper_scenes_are_lit_not_only_emissive(small_renders):
    """The paper_cameras scenes have lit diffuse surfaces: the sun-lit ones a single directional emitter
    under the direct integrator (no lighting noise), patio_table an area light under the path tracer."""
    from scenes.backend import import_mitsuba

    import_mitsuba(None)
    for name in SCENE_SETS["paper_cameras"]:
        shapes = SCENES[name].shapes()
        emitters = [k for k, v in shapes.items() if isinstance(v, dict) and ("emitter" in v or v.get("type") in
                                                                               ("directional", "constant"))]
        assert emitters, name
        assert SCENES[name].integrator["type"] in ("direct", "path")
        r = render_scene(name, preset="small", progress=False)
        assert np.isfinite(r.rgb).all() and r.rgb.mean() > 0.05, name
