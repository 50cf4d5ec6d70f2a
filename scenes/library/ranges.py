"""σ_gt range of each scene per resolution preset and f-number, measured on its ground truth (cached).

``python -m repro.render --list`` prints these: the numbers come from the same ground truth every
render carries (camera-space depth of the lens-centre ray through each pixel centre,
:func:`scenes.ground_truth.camera_space_depth`, then Eq. 5 and the box filter,
:func:`scenes.ground_truth.ground_truth_from_depth`), not from a formula typed in per scene. Depth
does not depend on the aperture, so one ray cast per preset gives the σ_gt of every f-number; no
image is path traced (a few seconds per scene at the ``full`` preset).
"""

from __future__ import annotations

import json

import numpy as np

from .base import DEFAULT_F_NUMBERS, PRESETS

__all__ = ["RANGES_FILE", "sigma_gt_ranges"]

#: File of a cache entry.
RANGES_FILE = "sigma_ranges.json"


def _measure(sdef, preset, f_numbers, *, mi, sigma_convention) -> dict:
    from ..ground_truth import camera_space_depth, ground_truth_from_depth
    from ..render import FILTER_SIGMA_PX

    camera = sdef.camera(preset)
    scene = mi.load_dict(sdef.build(camera, spp=1, seed=0))
    depth = camera_space_depth(scene, mi=mi)
    finite = np.isfinite(depth)
    out = {"depth_m": [float(depth[finite].min()), float(depth[finite].max())] if finite.any() else None,
           "miss_fraction": float(1.0 - finite.mean()), "f_numbers": {}}
    for n in f_numbers:
        gt = ground_truth_from_depth(depth, camera.replace(f_number=float(n)), sigma_convention=sigma_convention,
                                     filter_sigma_px=FILTER_SIGMA_PX)
        s = gt["sigma_px"].astype(np.float64)
        s = s[np.isfinite(s)]
        out["f_numbers"][f"{float(n):g}"] = {"min_px": float(s.min()), "p50_px": float(np.median(s)),
                                             "p95_px": float(np.percentile(s, 95)), "max_px": float(s.max())}
    return out


def sigma_gt_ranges(scene, *, presets=tuple(PRESETS), f_numbers=DEFAULT_F_NUMBERS, variant=None,
                    sigma_convention="line_spread", use_cache=True) -> dict:
    """σ_gt statistics of a scene's default camera for each preset and f-number.

    Parameters
    ----------
    scene : str or SceneDefinition
    presets : sequence of str, keyword-only
        Resolution presets (keys of :data:`.base.PRESETS`).
    f_numbers : sequence of float, keyword-only
        Apertures N > 0.
    variant : str, optional, keyword-only
        Mitsuba variant (default: the fastest that works).
    sigma_convention : {"line_spread", "erf_fit"}, keyword-only
    use_cache : bool, keyword-only
        Read/write ``cache_root() / "sigma_ranges"``, keyed by the scene's content hash, the camera,
        the f-numbers and the ground-truth code.

    Returns
    -------
    dict
        ``{preset: {"depth_m": [min, max] (metres), "miss_fraction": float,
        "f_numbers": {"8": {"min_px", "p50_px", "p95_px", "max_px"}, ...}}}`` (σ_gt in px over every
        pixel with a finite σ_gt).

    Notes
    -----
    One Mitsuba scene load and one lens-centre ray per pixel per preset
    (:func:`scenes.ground_truth.camera_space_depth`), then Eq. 5 for every f-number.
    """
    from ..backend import cache_root, import_mitsuba
    from ..render import scene_content_hash
    from defocus_cache import Cache, library_versions, source_fingerprint
    from .. import camera as camera_module, ground_truth, thin_lens
    from . import get_scene

    sdef = get_scene(scene)
    f_numbers = tuple(float(n) for n in f_numbers)
    if not f_numbers or any(not (n > 0 and np.isfinite(n)) for n in f_numbers):
        raise ValueError(f"f_numbers={f_numbers!r} is invalid; allowed: non-empty, each finite > 0")
    for p in presets:
        if p not in PRESETS:
            raise ValueError(f"unknown resolution preset {p!r}; choose one of {sorted(PRESETS)}")
    mi, chosen = import_mitsuba(variant)
    out = {}
    for preset in presets:
        key = {"kind": "sigma_ranges", "scene": sdef.name, "content": scene_content_hash(sdef, variant=chosen),
               "camera": sdef.camera(preset).to_dict(), "f_numbers": list(f_numbers), "variant": chosen,
               "sigma_convention": sigma_convention,
               "code": source_fingerprint(ground_truth, thin_lens, camera_module, __file__),
               "libraries": library_versions()}

        def build(folder, preset=preset):
            data = _measure(sdef, preset, f_numbers, mi=mi, sigma_convention=sigma_convention)
            (folder / RANGES_FILE).write_text(json.dumps(data, indent=1, sort_keys=True))

        if use_cache:
            folder = Cache(cache_root() / "sigma_ranges").get_or_build(key, build)
            out[preset] = json.loads((folder / RANGES_FILE).read_text())
        else:
            out[preset] = _measure(sdef, preset, f_numbers, mi=mi, sigma_convention=sigma_convention)
    return out
