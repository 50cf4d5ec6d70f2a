"""Mitsuba variant selection (scenes/backend.py): bad overrides fail clearly; the variant is recorded."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _env(**extra):
    e = dict(os.environ)
    e.update(extra)
    return e


def test_bogus_variant_env_is_a_clear_error():
    code = "from scenes.backend import select_variant\nselect_variant()"
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                       env=_env(DEFOCUS_MITSUBA_VARIANT="bogus"))
    assert p.returncode != 0
    last = p.stderr.strip().splitlines()[-1]
    assert "BackendError" in last and "bogus" in last and "llvm_ad_rgb" in last


def test_bogus_variant_env_in_cli_is_one_line_exit_2(tmp_path):
    p = subprocess.run([sys.executable, "-m", "repro.render", "planes", "--quiet", "-o", str(tmp_path / "x.exr")],
                       cwd=ROOT, capture_output=True, text=True, timeout=120,
                       env=_env(DEFOCUS_MITSUBA_VARIANT="bogus"))
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "bogus" in lines[0] and "Traceback" not in p.stderr
    assert list(tmp_path.iterdir()) == []


def test_bogus_variant_flag_raises():
    from scenes.backend import BackendError, select_variant

    with pytest.raises(BackendError, match="bogus"):
        select_variant("bogus")


def test_cache_root_honours_env(tmp_path, monkeypatch):
    from scenes.backend import cache_root

    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path / "c"))
    assert cache_root() == tmp_path / "c" and (tmp_path / "c").is_dir()


@pytest.mark.render
def test_chosen_variant_recorded_in_metadata():
    import numpy as np

    from scenes.backend import select_variant
    from scenes.render import render_scene

    r = render_scene("tilted_plane", preset="small", spp=4, progress=False, use_cache=False)
    assert r.metadata["variant"] == select_variant()
    import mitsuba as mi

    assert r.metadata["variant"] == mi.variant()
    assert r.metadata["versions"]["mitsuba"] == mi.__version__
    assert np.isfinite(r.rgb).all()


@pytest.mark.render
def test_scalar_variant_ground_truth_matches_llvm():
    """The scalar fallback (per-pixel Python loop) gives the same depth as the vectorised path."""
    import numpy as np

    from scenes.backend import probe_variant
    from scenes.library import SCENES
    from scenes.render import render_scene

    if not probe_variant("scalar_rgb")[0]:
        pytest.skip("scalar_rgb does not work here")
    cam = SCENES["planes"].camera("small", resolution=(40, 30))
    a = render_scene("planes", cam, spp=4, variant="scalar_rgb", use_cache=False, progress=False)
    b = render_scene("planes", cam, spp=4, use_cache=False, progress=False)
    assert a.metadata["variant"] == "scalar_rgb"
    np.testing.assert_allclose(a.depth, b.depth, atol=1e-5)
    np.testing.assert_array_equal(a.occlusion_boundary, b.occlusion_boundary)


def test_variant_env_var_is_part_of_the_selection_key(monkeypatch):
    """Setting $DEFOCUS_MITSUBA_VARIANT later in the same process changes the selection."""
    from scenes import backend

    probed = []
    monkeypatch.setattr(backend, "_available_variants", lambda: ("scalar_rgb", "llvm_ad_rgb"))
    monkeypatch.setattr(backend, "probe_variant", lambda v, **k: (probed.append(v), (True, "ok"))[1])
    backend._select_variant.cache_clear()
    try:
        monkeypatch.setenv(backend.VARIANT_ENV, "scalar_rgb")
        assert backend.select_variant() == "scalar_rgb"
        monkeypatch.setenv(backend.VARIANT_ENV, "llvm_ad_rgb")
        assert backend.select_variant() == "llvm_ad_rgb"
        assert backend.select_variant("scalar_rgb") == "scalar_rgb"  # an explicit request wins
        assert probed == ["scalar_rgb", "llvm_ad_rgb", "scalar_rgb"]
        assert backend.select_variant() == "llvm_ad_rgb" and len(probed) == 3  # remembered per key
    finally:
        backend._select_variant.cache_clear()


def test_probe_results_are_kept_but_a_timeout_is_probed_again(monkeypatch, tmp_path):
    from scenes import backend

    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path))
    calls = []

    def fake_run(cmd, **kw):
        calls.append(cmd[-1])
        if len(calls) == 1:
            raise subprocess.TimeoutExpired(cmd, kw["timeout"])
        return subprocess.CompletedProcess(cmd, 0, stdout="ok\n", stderr="")

    monkeypatch.setattr(backend.subprocess, "run", fake_run)
    assert backend.probe_variant("scalar_rgb", timeout=1)[1].startswith("probe timed out")
    assert not (tmp_path / "variant-probes.json").exists()  # a timeout is not stored
    assert backend.probe_variant("scalar_rgb") == (True, "ok")  # probed again
    assert backend.probe_variant("scalar_rgb") == (True, "ok") and len(calls) == 2  # now from the file
    assert (tmp_path / "variant-probes.json.lock").exists()  # written under a lock
