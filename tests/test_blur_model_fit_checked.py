"""model_fit_checked: the Eq. (2c) fit with a goodness-of-fit test (NaN where the fit is poor)."""

import math

import numpy as np
import pytest

from method.blur.estimators import BLUR_ESTIMATORS, estimate_blur
from method.blur.model_fit import _model_fit_with_residual
from method.edges.elder_zucker import detect_edges
from method.params import DefocusParams
from scenes.analytic import parallel_edges, step_edge
from tests import tolerances as tol

PARAMS = DefocusParams()
SIGMAS = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
_SHAPE = (80, 80)
_BORDER = 12
_NOISE = 2.0 / 255


def _pair(sc, border=_BORDER, near=1.5):
    """(model_fit, model_fit_checked) at detected edge pixels inside the border (near a true edge)."""
    em = detect_edges(sc.image)
    inner = np.zeros(sc.image.shape, dtype=bool)
    inner[border:-border, border:-border] = True
    sel = em.edges & inner
    if near is not None:
        sel &= np.abs(sc.edge_distance) < near
    mf = estimate_blur(sc.image, em, params=PARAMS, method="model_fit")
    ck = estimate_blur(sc.image, em, params=PARAMS, method="model_fit_checked")
    return mf[sel], ck[sel]


def _collect(scenes):
    mf, ck = zip(*(_pair(sc) for sc in scenes))
    return np.concatenate(mf), np.concatenate(ck)


def _check_same_where_kept(mf, ck):
    kept = np.isfinite(ck)
    # a value is only ever removed, never changed: bit-identical where kept
    assert np.array_equal(ck[kept], mf[kept])
    assert not np.any(kept & np.isnan(mf))
    return kept[np.isfinite(mf)].mean()


@pytest.fixture(scope="module")
def clean_steps():
    angles = [math.radians(a) for a in range(7, 360, 45)]
    return _collect(step_edge(_SHAPE, sigma=s, angle=a, offset=0.37) for s in SIGMAS for a in angles)


@pytest.fixture(scope="module")
def noisy_steps():
    angles = [math.radians(a) for a in (0, 33, 71, 128)]
    return _collect(step_edge(_SHAPE, sigma=s, angle=a, offset=0.21, noise_std=_NOISE, quantize_bits=8,
                              rng=int(10 * s) + i)
                    for s in SIGMAS for i, a in enumerate(angles))


def test_registered():
    assert BLUR_ESTIMATORS["model_fit_checked"].__name__ == "estimate_blur_model_fit_checked"
    assert DefocusParams(estimator="model_fit_checked").estimator == "model_fit_checked"


def test_clean_steps_same_sigma_and_kept(clean_steps):
    mf, ck = clean_steps
    assert np.isfinite(mf).sum() > 1000
    frac = _check_same_where_kept(mf, ck)
    print(f"\nclean steps: kept {100 * frac:.2f} % of {np.isfinite(mf).sum()} model_fit estimates")
    assert frac >= tol.MODEL_FIT_CHECKED_KEEP_CLEAN_MIN


def test_noisy_steps_same_sigma_and_kept(noisy_steps):
    mf, ck = noisy_steps
    assert np.isfinite(mf).sum() > 500
    frac = _check_same_where_kept(mf, ck)
    print(f"\nnoisy steps: kept {100 * frac:.2f} % of {np.isfinite(mf).sum()} model_fit estimates")
    assert frac >= tol.MODEL_FIT_CHECKED_KEEP_NOISY_MIN


def test_rejects_bars_and_thin_lines(clean_steps):
    """Two opposite edges close together (Fig. 4's bar; measured median model_fit error 2–39 % of σ
    at D = 2σ–4σ, σ = 2–3 px, cf. test_blur_estimators) and 1–2 px lines: not a blurred step."""
    cases = [parallel_edges((112, 112), sigma=s, spacing=k * s, angle=a, kind="bar", offset=0.3)
             for s in (2.0, 3.0) for k in (2, 3, 4) for a in (0.0, math.radians(30))]
    cases += [parallel_edges((112, 112), sigma=s, spacing=w, angle=a, kind="bar", offset=0.3)
              for s in (1.0, 2.0) for w in (1.0, 2.0) for a in (0.0, math.radians(30))]
    mf, ck = zip(*(_pair(sc, border=16, near=None) for sc in cases))
    mf, ck = np.concatenate(mf), np.concatenate(ck)
    assert np.isfinite(mf).sum() > 1000
    frac_bar = _check_same_where_kept(mf, ck)
    frac_clean = np.isfinite(clean_steps[1])[np.isfinite(clean_steps[0])].mean()
    print(f"\nbars / thin lines: kept {100 * frac_bar:.2f} % (clean steps {100 * frac_clean:.2f} %)")
    assert frac_bar < frac_clean
    assert frac_bar <= tol.MODEL_FIT_CHECKED_KEEP_BAR_MAX


def test_residual_range_and_threshold_extremes():
    sc = parallel_edges((96, 96), sigma=2.0, spacing=6.0, angle=math.radians(30), kind="bar", offset=0.3)
    em = detect_edges(sc.image)
    sigma_b, res = _model_fit_with_residual(sc.image, em, params=PARAMS)
    assert np.array_equal(np.isnan(res), np.isnan(sigma_b))
    assert np.all((res[np.isfinite(res)] >= 0) & (res[np.isfinite(res)] <= 1))
    all_kept = estimate_blur(sc.image, em, params=PARAMS.replace(fit_max_residual=1.0), method="model_fit_checked")
    mf = estimate_blur(sc.image, em, params=PARAMS, method="model_fit")
    assert np.array_equal(all_kept, mf, equal_nan=True)
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="fit_max_residual"):
            DefocusParams(fit_max_residual=bad)


def test_model_fit_regression_golden(goldens):
    """model_fit output on two fixed analytic images stays what it was (golden summary numbers).

    The residual hook was added without changing model_fit (checked bit for bit when it was added);
    this keeps watching it, with a drift allowance for FFT/library round-off.
    """
    cases = {
        "noisy_step": step_edge((64, 64), sigma=2.5, angle=math.radians(23), offset=0.31,
                                noise_std=2 / 255, quantize_bits=8, rng=5),
        "bar": parallel_edges((96, 96), sigma=2.0, spacing=6.0, angle=math.radians(30), kind="bar", offset=0.3),
    }
    summary = {}
    for name, sc in cases.items():
        em = detect_edges(sc.image)
        est = estimate_blur(sc.image, em, params=PARAMS, method="model_fit")
        v = est[np.isfinite(est)]
        summary[name] = {"n": int(v.size), "mean": float(v.mean()), "median": float(np.median(v)),
                         "min": float(v.min()), "max": float(v.max())}
    goldens.check("model_fit_regression", summary, rtol=tol.MODEL_FIT_REGRESSION_RTOL, atol=tol.MODEL_FIT_REGRESSION_ATOL)
