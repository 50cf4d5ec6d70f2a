"""The procedural scene family: seed splits, the draw, determinism across processes, the σ_gt range.

Layout tests need no renderer (the draw is plain NumPy); the cross-process and σ_gt tests load the
scenes in Mitsuba (lens-centre rays only, and one tiny render) and are marked ``render``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scenes.library.procedural import (CAMERA_FOCUS_RANGES_M, LIGHTING_KINDS, NEAR_COC_PX, OBJECT_KINDS, SPLITS,
                                       check_seed_range, draw_fresh_start, draw_layout, procedural_name,
                                       procedural_scene, seed_of, split_of)

ROOT = Path(__file__).resolve().parents[1]


def test_splits_are_disjoint_and_every_seed_has_at_most_one():
    spans = sorted((s.start, s.stop, s.name) for s in SPLITS.values())
    assert [n for *_, n in spans] == ["dev", "test", "fresh"]
    for (a0, a1, _), (b0, b1, _) in zip(spans, spans[1:]):
        assert a1 <= b0, "splits overlap"
    for s in SPLITS.values():
        assert split_of(s.start) == s.name and split_of(s.stop - 1) == s.name
        assert split_of(s.stop) != s.name
    assert split_of(200_000) is None  # the gap between test and fresh belongs to no split


@pytest.mark.parametrize("split, start, n, needle", [
    ("dev", 99_999, 2, "overlaps the test split"),
    ("test", 99_999, 1, "overlaps the dev split"),
    ("test", 199_990, 20, "allowed: seeds in [100000, 200000)"),
    ("fresh", 10, 1, "overlaps the dev split"),
    ("dev", 0, 0, "N=0"),
    ("dev", 0, -3, "N=-3"),
    ("nope", 0, 1, "unknown split"),
])
def test_seed_ranges_outside_their_split_are_refused(split, start, n, needle):
    with pytest.raises(ValueError, match=needle.replace("[", r"\[").replace(")", r"\)")):
        check_seed_range(split, start, n)


def test_seed_ranges_inside_their_split_are_accepted():
    assert check_seed_range("dev", 99_998, 2) == range(99_998, 100_000)
    assert check_seed_range("test", 100_000, 5) == range(100_000, 100_005)


def test_fresh_starts_are_drawn_inside_the_fresh_split():
    starts = [draw_fresh_start(50) for _ in range(20)]
    assert all(check_seed_range("fresh", s, 50) for s in starts)
    assert len(set(starts)) > 1  # drawn, not fixed


def test_same_seed_same_layout_other_seed_other_layout():
    for seed in (0, 1, 100_000, 1_234_567):
        assert draw_layout(seed) == draw_layout(seed)
        assert draw_layout(seed) != draw_layout(seed + 1)
    names = {procedural_scene(s).description for s in range(20)}
    assert len(names) == 20


def test_layouts_draw_the_stated_family():
    """Over 300 seeds: 3-12 objects of every kind, every camera and lighting kind, the first object well in
    front of the subject with its centre in the frame, the others between it and the background."""
    cams, kinds, lights, counts = set(), set(), [], []
    for seed in range(300):
        lay = draw_layout(seed)
        d, objs = lay["focus_distance_m"], lay["objects"]
        lo, hi = CAMERA_FOCUS_RANGES_M[lay["camera_name"]]
        assert lo <= d <= hi and 3 <= len(objs) <= 12
        assert math.isclose(lay["subject"]["depth_m"], d, rel_tol=1e-12)
        first = objs[0]
        assert -NEAR_COC_PX[1] <= first["coc_f2_px"] <= -NEAR_COC_PX[0]
        assert abs(first["u"]) <= 0.8 and abs(first["v"]) <= 0.8
        assert any(o["depth_m"] > d for o in objs)  # something behind the subject
        assert all(0.02 < o["depth_m"] < lay["background"]["depth_m"] for o in objs)
        cams.add(lay["camera_name"])
        kinds.update(o["kind"] for o in objs)
        lights.append(lay["lighting"])
        counts.append(len(objs))
    assert cams == set(CAMERA_FOCUS_RANGES_M) and kinds == set(OBJECT_KINDS) and set(lights) == set(LIGHTING_KINDS)
    assert 0.15 < lights.count("lit") / len(lights) < 0.35  # LIT_SHARE = 0.25
    assert min(counts) == 3 and max(counts) == 12


def test_drawn_defocus_is_eq5_of_the_drawn_depth():
    """Oracle: each object's CoC at f/2 (640 px) equals the camera's own Eq. (5) at the object's depth."""
    for seed in (3, 8, 100_004):
        lay = draw_layout(seed)
        sdef = procedural_scene(seed)
        cam = sdef.camera("full", f_number=2.0)
        for o in lay["objects"]:
            c = float(cam.coc_px(o["depth_m"]))
            assert math.isclose(abs(o["coc_f2_px"]), c, rel_tol=1e-9)


def test_names_resolve_to_the_same_scene_and_bad_ones_are_refused():
    from scenes import get_scene

    assert get_scene(procedural_name(42)) is procedural_scene(42)
    forced = get_scene("procedural_42_nikon_d50_180mm")
    assert forced.camera_name == "nikon_d50_180mm" and forced.name == "procedural_42_nikon_d50_180mm"
    assert seed_of("procedural_42") == (42, None)
    with pytest.raises(ValueError, match="camera='full_frame' is invalid"):
        get_scene("procedural_42_full_frame")
    with pytest.raises(ValueError, match="unknown scene"):
        get_scene("procedural_x")
    with pytest.raises(ValueError, match="seed=-1"):
        procedural_scene(-1)


_PROBE = r"""
import json, sys
from scenes.backend import import_mitsuba
from scenes.render import render_scene, scene_content_hash
from scenes.library import get_scene
mi, variant = import_mitsuba(None)
out = {}
for name in sys.argv[1:]:
    sdef = get_scene(name)
    r = render_scene(name, sdef.camera(resolution=(40, 30), f_number=2.0), spp=4, use_cache=False, progress=False)
    out[name] = {"hash": scene_content_hash(sdef, variant=variant), "sigma": r.sigma_px.astype(float).ravel().tolist()}
print(json.dumps(out))
"""


@pytest.mark.render
def test_same_seed_same_content_hash_and_sigma_gt_in_two_processes(tmp_path, monkeypatch):
    """This process and a fresh one, each with its own empty cache (no shared hash memo): equal hashes and
    σ_gt per seed, different hashes for different seeds."""
    import shutil

    from scenes import render as render_module
    from scenes.backend import cache_root

    names = ["procedural_4", "procedural_100010"]  # an emission-only and a lit scene, few objects each
    caches = [tmp_path / "here", tmp_path / "there"]
    probes = cache_root() / "variant-probes.json"  # the Mitsuba variant probe is not under test: reuse it
    for c in caches:
        c.mkdir()
        if probes.is_file():
            shutil.copy(probes, c / probes.name)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(caches[1])}
    env.setdefault("DRJIT_CACHE_DIR", str(ROOT / ".cache" / "drjit"))
    proc = subprocess.Popen([sys.executable, "-c", _PROBE, *names], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(caches[0]))
    monkeypatch.setattr(render_module, "_CONTENT_HASHES", {})
    from scenes.backend import import_mitsuba

    _, variant = import_mitsuba(None)
    here = {}
    for name in names:
        sdef = procedural_scene(seed_of(name)[0])
        r = render_module.render_scene(name, sdef.camera(resolution=(40, 30), f_number=2.0), spp=4, use_cache=False,
                                       progress=False)
        here[name] = {"hash": render_module.scene_content_hash(sdef, variant=variant), "sigma": r.sigma_px}
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr[-2000:]
    there = json.loads(stdout.strip().splitlines()[-1])
    for n in names:
        assert here[n]["hash"] == there[n]["hash"]
        assert np.array_equal(here[n]["sigma"].astype(float).ravel(), np.array(there[n]["sigma"]))
        assert np.ptp(here[n]["sigma"]) > 0.3  # a real σ_gt map (40 px wide), not a constant
    assert here[names[0]]["hash"] != here[names[1]]["hash"]


@pytest.mark.render
@pytest.mark.parametrize("seed", [4, 100_006])  # a PowerShot 7.8 mm and a Nikon 180 mm scene
def test_sigma_gt_spans_in_focus_to_8px_at_f2_full_preset(seed):
    """Measured on the ground truth at 640×480 (lens-centre rays, no image rendered): at f/2 σ_gt reaches the
    box-filter floor (the subject) and ≥ 8 px (the object in front); σ_gt ∝ 1/N in quadrature with the box."""
    from scenes.library.ranges import sigma_gt_ranges

    r = sigma_gt_ranges(procedural_name(seed), presets=("full",), f_numbers=(2.0, 8.0))["full"]
    f2, f8 = r["f_numbers"]["2"], r["f_numbers"]["8"]
    assert f2["min_px"] <= 0.5 and f2["max_px"] >= 8.0
    assert r["miss_fraction"] == 0.0  # the background fills the frame
    box = 1.0 / 12.0
    assert math.isclose(f8["max_px"], math.sqrt((f2["max_px"] ** 2 - box) / 16.0 + box), rel_tol=1e-4)


def test_render_image_and_input_image_pass_the_noise_level_and_seed_through():
    """No renderer: a synthetic Render. The noise level and its seed reach the camera pipeline."""
    from experiments.evaluation import input_image
    from scenes.display import camera_image
    from scenes.render import Render

    h, w = 32, 48
    rgb = np.full((h, w, 3), 0.2, np.float32)
    z = np.zeros((h, w), np.float32)
    r = Render(rgb=rgb, depth=z + 1, coc_px=z, sigma_px=z, occlusion_boundary=z > 0, metadata={})
    clean = input_image(r)
    noisy = input_image(r, noise="iso800", rng=7)
    assert np.array_equal(clean, camera_image(rgb, quantize_bits=8))
    assert np.array_equal(noisy, camera_image(rgb, quantize_bits=8, noise="iso800", rng=7))
    assert np.array_equal(noisy, input_image(r, noise="iso800", rng=7))  # same seed, same noise
    assert not np.array_equal(noisy, input_image(r, noise="iso800", rng=8))
    assert 0.01 < float(np.std(noisy - clean)) < 0.1  # iso800 at linear 0.2: σ ≈ 0.018 linear, ≈ 0.02 in sRGB
    with pytest.raises(ValueError, match="unknown noise level"):
        r.image(noise="iso9")
