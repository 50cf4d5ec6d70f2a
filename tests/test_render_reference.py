"""A rendered reference (Mitsuba test_renders.py style): the small ``planes`` render at f/8 is compared
with ``tests/references/planes_small_f8.exr`` within stated tolerances; on failure diagnostic images
(render, reference, |difference|) are written to ``tests/_failures/``. Regenerate deliberately with
``pytest --regen-references`` (then review and commit the EXR)."""

from pathlib import Path

import numpy as np
import pytest

from tests.tolerances import REF_DEPTH_RTOL, REF_RGB_MAX_BIAS, REF_RGB_RMSE, REF_SIGMA_ATOL_PX

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "tests" / "references" / "planes_small_f8.exr"
FAILURES = ROOT / "tests" / "_failures"


def _write_diagnostics(render_rgb, ref_rgb, name):
    from PIL import Image

    from scenes.display import linear_to_srgb

    FAILURES.mkdir(exist_ok=True)
    diff = np.abs(render_rgb - ref_rgb)
    scale = max(float(diff.max()), 1e-6)
    for tag, img in (("render", linear_to_srgb(render_rgb)), ("reference", linear_to_srgb(ref_rgb)),
                     ("absdiff_normalised", diff / scale)):
        Image.fromarray(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)).save(FAILURES / f"{name}.{tag}.png")
    return FAILURES


@pytest.mark.render
def test_planes_small_matches_reference(request):
    from scenes import render_scene
    from scenes.exr import read_exr

    r = render_scene("planes", preset="small", f_number=8, progress=False)
    if request.config.getoption("--regen-references"):
        REFERENCE.parent.mkdir(exist_ok=True)
        r.save(REFERENCE)
        pytest.skip(f"reference rewritten: {REFERENCE}")
    assert REFERENCE.exists(), f"missing {REFERENCE}; run pytest --regen-references"
    ref = read_exr(REFERENCE)
    rgb, ref_rgb = r.rgb.astype(np.float64), ref["RGB"].astype(np.float64)
    rmse = float(np.sqrt(np.mean((rgb - ref_rgb) ** 2)))
    bias = float(np.mean(rgb - ref_rgb))
    ok = rmse <= REF_RGB_RMSE and abs(bias) <= REF_RGB_MAX_BIAS
    if not ok:
        where = _write_diagnostics(rgb, ref_rgb, "planes_small_f8")
        pytest.fail(f"render differs from the reference: RMSE {rmse:.4g} (allowed {REF_RGB_RMSE}), mean "
                    f"difference {bias:+.4g} (allowed ±{REF_RGB_MAX_BIAS}); diagnostic images in {where}")
    # Ground truth is a deterministic ray cast: it must match tightly (inf = miss on both sides).
    np.testing.assert_allclose(r.depth, ref["Z"], rtol=REF_DEPTH_RTOL)
    np.testing.assert_allclose(r.sigma_px, ref["sigma"], rtol=0, atol=REF_SIGMA_ATOL_PX)
