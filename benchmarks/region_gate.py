"""The region cue's adequacy gate: which windows it keeps per texture family, and how right they are.

``.venv/bin/python benchmarks/region_gate.py [--seeds 0 1] [--noise iso100] [--renders]``

Lens mosaics (:func:`scenes.analytic.lens.lens_mosaic`: disk PSF in linear light, the camera's noise,
sRGB, 8 bits) of every texture family, tiles of 128 px at σ 1, 2, 3, 4, 6, 8; the local-spectrum
estimator with the disk model on a 16-px grid of windows. For each gate of :data:`GATES` (deviance per
band ≤ D, relative std ≤ R, σ̂ below the grid's top) it prints, per family, the share of windows kept
(away from tile seams), their median relative error and the share within 10 % of σ_gt; and the same
with the image decoded to linear light first (the noise estimate then reads the dark regions).
``--renders`` instead scores the gated cue on Mitsuba thin-lens renders (:data:`RENDERS`, small and full
preset, f/8 f/4 f/2, through the render cache): share of valid pixels measured and the median relative
error there. The numbers of docs/region-blur.md ("Under lens blur") come from this script.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

#: (label, max deviance per band, max relative std, top margin).
GATES = (("no gate", np.inf, np.inf, 1.0), ("D ≤ 3, R ≤ 0.08", 3.0, 0.08, 1.1),
         ("D ≤ 2, R ≤ 0.05 (adequacy)", 2.0, 0.05, 1.1), ("D ≤ 2, R ≤ 0.03", 2.0, 0.03, 1.1))
SIGMAS = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
#: Scenes of ``--renders``.
RENDERS = ("portrait_garden", "street_figures", "heron_at_the_lake", "planes", "portrait")


def _renders():
    from experiments.evaluation import ground_truth_sigma, input_image
    from method import DefocusParams
    from method.blur.region_estimators import estimate_region_blur
    from scenes import render_scene

    p = DefocusParams.preset("robust", region_estimator="local_spectrum", region_psf="disk", region_gate="adequacy")
    print("scene, f-number, preset: share of valid pixels measured, median relative error, share within 10 %")
    for scene in RENDERS:
        for f in (8.0, 4.0, 2.0):
            for preset in ("small", "full"):
                r = render_scene(scene, preset=preset, f_number=f, progress=False)
                gt = ground_truth_sigma(r)
                s, _ = estimate_region_blur(input_image(r), params=p)
                ok = np.isfinite(s) & np.isfinite(gt) & ~r.occlusion_boundary
                rel = (s[ok] - gt[ok]) / gt[ok]
                med = f"{np.median(rel):+.3f}" if ok.any() else "  —  "
                within = f"{np.mean(np.abs(rel) < 0.1):.2f}" if ok.any() else " — "
                print(f"  {scene:18s} f/{f:g} {preset:5s} {ok.mean():.2f}  {med}  {within}")


def _windows(image, gate, *, linear=False):
    from method import DefocusParams
    from method.blur.local_spectrum import AdequacyGate, local_spectrum_grid
    from method.luma import measure_luminance

    p = DefocusParams.preset("robust")
    g = measure_luminance(image, "linear" if linear else "display")
    return local_spectrum_grid(g, psf="disk", noise_model=p.region_noise_model, sigma_min=p.region_sigma_min,
                               sigma_max=p.region_sigma_max, window_min=p.region_window_min,
                               window_max=p.region_window_max, window_scale=p.region_window_scale, stride=16,
                               gate=AdequacyGate(*gate))


def main(argv=None):
    from scenes.analytic.families import TEXTURE_FAMILIES
    from scenes.analytic.lens import lens_mosaic

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--noise", default="iso100")
    ap.add_argument("--renders", action="store_true", help="score the gated cue on thin-lens renders instead")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.renders:
        _renders()
        return
    mosaics = {f: [lens_mosaic(family=f, psf="disk", sigmas=SIGMAS, tile=128, cols=3, noise=args.noise, rng=s)
                   for s in args.seeds] for f in TEXTURE_FAMILIES}
    runs = [(label, gate, False) for label, *gate in GATES] + [("linear input, adequacy", GATES[2][1:], True)]
    for label, gate, linear in runs:
        print(f"\n{label}: family, share kept, median relative error, share within 10 %")
        for fam, ms in mosaics.items():
            rel, total = [], 0
            for m in ms:
                out = _windows(m.image, gate, linear=linear)
                cy, cx = out["cy"], out["cx"]
                inner = ~m.boundary[cy][:, cx]
                gt = m.sigma[cy][:, cx]
                ok = inner & np.isfinite(out["sigma"])
                total += int(inner.sum())
                rel.append(((out["sigma"] - gt) / gt)[ok])
            r = np.concatenate(rel)
            med = f"{np.median(r):+.2f}" if r.size else "  — "
            within = f"{np.mean(np.abs(r) < 0.1):.2f}" if r.size else " — "
            print(f"  {fam:13s} {r.size / max(total, 1):5.2f}  {med}  {within}")


if __name__ == "__main__":
    main()
