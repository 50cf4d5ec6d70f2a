"""The region (local-spectrum) blur cue on its own: raw per-window accuracy, information, noise, speed.

``.venv/bin/python benchmarks/region_accuracy.py [--only accuracy windows variants info noise mosaic speed]``

Every number of docs/region-blur.md's sections "Measured accuracy", "Information and noise" and "Speed"
comes from this script (the section "Under lens blur" from ``benchmarks/region_gate.py``). The cue is
:func:`method.blur.local_spectrum.local_spectrum_grid` (per window) or
:func:`method.blur.region_estimators.estimate_region_blur` (per pixel) with the paper preset's region
fields (window 12·σ̂, 16–96 px, stride 32, white noise, σ grid 0–12 px) unless a row says otherwise.

Images (all 8 bits, Gaussian noise of the std given, seeds 0 and 1):

* Gaussian blur: :func:`scenes.analytic.dead_leaves` (grey, 256², radii 2–32 px, 4× supersampled,
  blurred on the fine grid, point-sampled), σ = the Gaussian's std;
* disk blur: :func:`scenes.analytic.lens.lens_mosaic` of the ``dead_leaves`` family as one 256-px tile, a
  uniform disk ⊗ the 1-px box in display values, 8× supersampled, σ the harness's reported σ
  (√((c/4)² + 1/12) px), its luminance (:func:`method.luma.luminance`);
* the 1 MP mosaic: four 512² dead-leaves quadrants (Gaussian σ 1, 2, 4, 8), errors 64 px or more from
  the seams and the border.

Per-window statistics are over every window with a measure (σ̂ finite): median signed error, mean
absolute error and standard deviation of σ̂ − σ, px.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

NOISES = (1.0, 2.0)                                # /255, accuracy tables
GAUSS_SIGMAS = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
DISK_SIGMAS = (1.0, 2.0, 4.0, 6.0)
SEEDS = (0, 1)
SIZE = 256
SECTIONS = ("accuracy", "windows", "variants", "info", "noise", "mosaic", "speed")


def _params(**changes):
    from method import DefocusParams

    return dataclasses.replace(DefocusParams(region_estimator="local_spectrum"), **changes)


def _camera(image, noise, seed):
    from scenes.analytic import degrade

    return degrade(image, noise_std=noise / 255, quantize_bits=8, rng=1000 + seed)


def _gaussian_image(sigma, noise, seed):
    from scenes.analytic import dead_leaves

    return _camera(dead_leaves((SIZE, SIZE), sigma=sigma, rng=seed), noise, seed)


def _disk_image(sigma, noise, seed):
    from method.luma import luminance
    from scenes.analytic.lens import lens_mosaic

    m = lens_mosaic(family="dead_leaves", psf="disk", sigmas=(sigma,), tile=SIZE, cols=1, light="display",
                    supersample=8, quantize_bits=None, rng=seed)
    return _camera(luminance(m.image), noise, seed)


def _grid(gray, *, psf="gaussian", likelihood="profile", **changes):
    from method.blur.local_spectrum import local_spectrum_grid

    p = _params(**changes)
    return local_spectrum_grid(gray, psf=psf, noise_model=p.region_noise_model, sigma_min=p.region_sigma_min,
                               sigma_max=p.region_sigma_max, window_min=p.region_window_min,
                               window_max=p.region_window_max, window_scale=p.region_window_scale,
                               stride=p.region_stride, likelihood=likelihood)


def _errors(kind, sigma, noise, **changes):
    """σ̂ − σ and the information of every measured window over :data:`SEEDS`."""
    make = _gaussian_image if kind == "gaussian" else _disk_image
    likelihood = changes.pop("likelihood", "profile")
    err, info = [], []
    for seed in SEEDS:
        g = _grid(make(sigma, noise, seed), psf=kind, likelihood=likelihood, **changes)
        ok = np.isfinite(g["sigma"])
        err.append(g["sigma"][ok] - sigma)
        info.append(g["information"][ok])
    return np.concatenate(err), np.concatenate(info)


def _stats(err) -> str:
    if not err.size:
        return "no measure"
    return f"{np.median(err):+.2f} / {np.mean(np.abs(err)):.2f} / {np.std(err):.2f}"


def accuracy():
    print("## raw per-window accuracy: median signed error / MAE / std of σ̂ − σ, px\n")
    print("| σ px | " + " | ".join(f"{k}, {n:g}/255" for k in ("Gaussian", "disk") for n in NOISES) + " |")
    print("|---:|" + "---|" * 2 * len(NOISES))
    for s in sorted(set(GAUSS_SIGMAS) | set(DISK_SIGMAS)):
        cells = [_stats(_errors("gaussian", s, n)[0]) if s in GAUSS_SIGMAS else "" for n in NOISES]
        cells += [_stats(_errors("disk", s, n)[0]) if s in DISK_SIGMAS else "" for n in NOISES]
        print(f"| {s:g} | " + " | ".join(cells) + " |", flush=True)


def windows():
    print("\n## window choices (1/255): median / MAE / std, px\n")
    for label, kind, s, changes in (("Gaussian σ 8, windows ≤ 96 px (default)", "gaussian", 8.0, {}),
                                    ("Gaussian σ 8, windows ≤ 128 px", "gaussian", 8.0, {"region_window_max": 128}),
                                    ("Gaussian σ 6, window 12σ̂ (default)", "gaussian", 6.0, {}),
                                    ("Gaussian σ 6, window 9σ̂", "gaussian", 6.0, {"region_window_scale": 9.0})):
        print(f"- {label}: {_stats(_errors(kind, s, 1.0, **changes)[0])}")
    for scale in (12.0, 9.0):
        print(f"- disk, window {scale:g}σ̂, stride 16: σ 2 / 4 / 6:")
        for s in (2.0, 4.0, 6.0):
            err, info = _errors("disk", s, 1.0, region_window_scale=scale, region_stride=16)
            bad = np.abs(err) > 0.25 * s
            ratio = np.median(info[~bad]) / np.median(info[bad]) if bad.any() and (~bad).any() else float("nan")
            print(f"  - σ {s:g}: {_stats(err)}; {100 * bad.mean():.0f} % of windows off by > 25 % of σ, their "
                  f"median information {ratio:.1f}× below the others'; information-weighted MAE "
                  f"{np.sum(info * np.abs(err)) / np.sum(info):.2f} px")


def variants():
    print("\n## variants, Gaussian, 1/255: median / MAE at σ 1 / 3 / 6, px\n")
    for label, changes in (("profile likelihood, white noise (default)", {}), ("gsm", {"likelihood": "gsm"}),
                           ("spectrum_or_white", {"region_noise_model": "spectrum_or_white"}),
                           ("spectrum", {"region_noise_model": "spectrum"})):
        cells = []
        for s in (1.0, 3.0, 6.0):
            err = _errors("gaussian", s, 1.0, **dict(changes))[0]
            cells.append(f"{np.median(err):+.2f}/{np.mean(np.abs(err)):.2f}" if err.size else "none")
        print(f"- {label}: " + ", ".join(cells))


def info():
    from method.blur.local_spectrum import local_spectrum_grid

    print("\n## information per window vs noise (Gaussian, stride 32)\n")
    print("| noise /255 | σ 2: median info 1/px² | 1/√info px | observed sd px | σ 4: median info | 1/√info | sd |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n in (0.5, 1.0, 2.0, 4.0, 8.0):
        cells = []
        for s in (2.0, 4.0):
            err, inf = _errors("gaussian", s, n)
            med = float(np.median(inf))
            cells += [f"{med:.0f}", f"{med ** -0.5:.3f}", f"{np.std(err):.3f}"]
        print(f"| {n:g} | " + " | ".join(cells) + " |", flush=True)
    measured = []
    for n in (1.0, 2.0, 4.0):
        for seed in range(4):
            g = local_spectrum_grid(_camera(np.full((SIZE, SIZE), 0.5), n, seed))
            measured.append((int(np.isfinite(g["sigma"]).sum()), g["sigma"].size))
    flat = local_spectrum_grid(np.full((SIZE, SIZE), 0.5))
    print(f"\nnoise-only images (1, 2, 4/255, 4 × {SIZE}² each): {sum(m for m, _ in measured)} of "
          f"{sum(t for _, t in measured)} windows measured; a flat image: {int(np.isfinite(flat['sigma']).sum())}")


def _haar_mad(gray) -> float:
    """Noise std read as the MAD of the finest Haar diagonal detail / 0.6745 (Donoho; what
    ``skimage.restoration.estimate_sigma`` computes with PyWavelets' ``db1``)."""
    g = gray[: gray.shape[0] // 2 * 2, : gray.shape[1] // 2 * 2]
    d = (g[0::2, 0::2] - g[0::2, 1::2] - g[1::2, 0::2] + g[1::2, 1::2]) / 2
    return float(np.median(np.abs(d)) / 0.6745)


def noise():
    from method.blur.local_spectrum import estimate_noise_variance
    from scenes.analytic import dead_leaves

    print("\n## noise estimate (dead leaves, seeds 0–1): read std ×255 for the true std ×255\n")
    for s in (1.0, 4.0):
        for n in (1.0, 4.0, 8.0):
            ours = [255 * estimate_noise_variance(_gaussian_image(s, n, seed)) ** 0.5 for seed in SEEDS]
            mad = [255 * _haar_mad(_gaussian_image(s, n, seed)) for seed in SEEDS]
            print(f"- σ {s:g}, {n:g}/255: quiet blocks {min(ours):.2f}–{max(ours):.2f}; "
                  f"finest Haar diagonal MAD {min(mad):.2f}–{max(mad):.2f}")
    clean = dead_leaves((SIZE, SIZE), sigma=1.0, rng=0)
    print(f"- σ 1, no noise, 8 bits: quiet blocks {255 * estimate_noise_variance(_camera(clean, 0.0, 0)) ** 0.5:.2f}"
          f" (the quantisation floor is {1 / 12 ** 0.5:.2f})")


def _mosaic():
    from scenes.analytic import dead_leaves

    q = 512
    img, truth = np.zeros((2 * q, 2 * q)), np.zeros((2 * q, 2 * q))
    for i, s in enumerate((1.0, 2.0, 4.0, 8.0)):
        y, x = divmod(i, 2)
        img[y * q:(y + 1) * q, x * q:(x + 1) * q] = dead_leaves((q, q), sigma=s, rng=10 + i)
        truth[y * q:(y + 1) * q, x * q:(x + 1) * q] = s
    inner = np.zeros_like(truth, dtype=bool)
    for y in range(2):
        for x in range(2):
            inner[y * q + 64:(y + 1) * q - 64, x * q + 64:(x + 1) * q - 64] = True
    return _camera(img, 1.0, 0), truth, inner


def mosaic():
    from method.blur.region_estimators import estimate_region_blur

    print("\n## 1 MP mosaic (σ 1, 2, 4, 8 quadrants, 1/255), per pixel: median error / MAE px per quadrant\n")
    img, truth, inner = _mosaic()
    for stride in (32, 16):
        sigma, _ = estimate_region_blur(img, params=_params(region_stride=stride))
        cells = []
        for s in (1.0, 2.0, 4.0, 8.0):
            e = (sigma - truth)[inner & (truth == s) & np.isfinite(sigma)]
            cells.append(f"σ {s:g}: {np.median(e):+.2f} / {np.mean(np.abs(e)):.2f}")
        print(f"- stride {stride}: " + "; ".join(cells))


def speed():
    from skimage import data

    from method.blur.region_estimators import estimate_region_blur
    from method.luma import luminance

    print("\n## speed: estimate_region_blur, 5 calls per row in one process (the first row's first call also "
          "builds the leakage tables)\n")
    img = _mosaic()[0]
    coffee = luminance(data.coffee() / 255.0)
    print("| image | kernel, stride | first call s | best of 5 s | CPU s (best) |")
    print("|---|---|---:|---:|---:|")
    for name, gray in (("1 MP mosaic", img), (f"coffee {coffee.shape[1]}×{coffee.shape[0]}", coffee)):
        for psf in ("gaussian", "disk"):
            for stride in (32, 16):
                p = _params(region_psf=psf, region_stride=stride)
                runs = []
                for _ in range(5):
                    t, c = time.perf_counter(), time.process_time()
                    estimate_region_blur(gray, params=p)
                    runs.append((time.perf_counter() - t, time.process_time() - c))
                best = min(runs)
                print(f"| {name} | {psf}, {stride} | {runs[0][0]:.2f} | {best[0]:.2f} | {best[1]:.2f} |", flush=True)
    import os

    print(f"\nload average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS), help="sections to run")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    for name in SECTIONS:
        if name in args.only:
            globals()[name]()


if __name__ == "__main__":
    main()
