"""Procedural scenes drawn from a seed: a family of scenes nobody tuned on, with held-out splits.

:func:`procedural_scene` turns an integer seed into a :class:`~.base.SceneDefinition` named
``procedural_<seed>``: one of the paper's cameras (:data:`scenes.camera.PAPER_CAMERAS`) focused at a
distance drawn for it, a *subject* at the focus distance, 3–12 objects (planes, possibly tilted;
boxes; spheres; cylinders) at depths from well in front of it to far behind, and a background
(a fronto-parallel wall, often with a floor receding to it). Every surface carries a texture of the
texture families (:data:`scenes.analytic.families.TEXTURE_FAMILIES`: dead leaves, photo crops,
checks, stripes, text, brick, flat patches, smooth shading). A share :data:`LIT_SHARE` of the seeds
is lit by an area light (soft shadows) with glossy surfaces, path traced; the others are
emission-only like the tabletop scenes (every surface shows its texture as emitted radiance; no
lighting noise, several times cheaper to render).

Depths are drawn in *defocus*, not in metres: the circle of confusion of a depth z is
c(z) = K·|1/D − 1/z| (Eq. 5 with K = f²·D/(N·(D − f))/pitch), so each object gets a signed CoC at
the reference aperture f/2 and the ``full`` preset (640 px wide) and its depth follows. The first
object is always well in front (c between :data:`NEAR_COC_PX`), so σ_gt = c/4 (⊕ the pixel box)
spans from in focus (the subject, ≤ 0.5 px) to ≥ 8 px at f/2 on every seed (checked on the ground
truth by the tests); at f/4 and f/8 the same scene gives half and a quarter of that blur.
Object sizes scale with their depth (a fraction of the frame's half-width), so every object covers a
similar share of the image whatever its distance.

Seeds and splits (:data:`SPLITS`): ``dev`` seeds are for tuning, ``test`` seeds are for reporting,
and ``fresh`` seeds are drawn at run time (:func:`draw_fresh_start`) so that an evaluation can always
see scenes nobody has looked at. The rule: tune on ``dev``, report ``test`` and ``fresh``.

The draw (:func:`draw_layout`) is plain NumPy from ``SeedSequence([seed, _DOMAIN])``: the same seed
gives the same layout, the same textures and so the same scene content hash
(:func:`scenes.render.scene_content_hash`) in any process on any machine with the same library
versions. Mitsuba is imported only inside the shape builder (:mod:`.procedural_shapes`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import secrets
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from ..camera import PAPER_CAMERAS
from .base import EMISSION_ONLY_INTEGRATOR, PATH_INTEGRATOR, REF_WIDTH_PX, SceneDefinition, spp_per_preset

__all__ = [
    "CAMERA_FOCUS_RANGES_M",
    "LIGHTING_KINDS",
    "LIT_SHARE",
    "NEAR_COC_PX",
    "OBJECT_KINDS",
    "PROCEDURAL_F_NUMBERS",
    "PROCEDURAL_PREFIX",
    "REF_F_NUMBER",
    "SPLITS",
    "SeedSplit",
    "check_seed_range",
    "draw_fresh_start",
    "draw_layout",
    "is_procedural_name",
    "procedural_name",
    "procedural_scene",
    "seed_of",
    "split_of",
]

#: Scene names are ``procedural_<seed>`` (``procedural_<seed>_<camera>`` with a camera forced).
PROCEDURAL_PREFIX = "procedural"
#: The apertures an evaluation of the family uses by default: σ_gt ∝ 1/N.
PROCEDURAL_F_NUMBERS = (8.0, 4.0, 2.0)
#: Lighting of a scene: ``emission`` (textures emitted, ``path`` max_depth 1) or ``lit`` (area light,
#: soft shadows, glossy surfaces, :data:`.base.PATH_INTEGRATOR`).
LIGHTING_KINDS = ("emission", "lit")
#: Share of the seeds that are lit (path traced). Chosen for the render budget: a lit scene costs
#: several times an emission-only one (docs/procedural.md has the measured times).
LIT_SHARE = 0.25
#: Samples per pixel (squares: Mitsuba's multijitter sampler takes them as they are). Emission-only
#: scenes have no lighting noise, only the lens/pixel integral; lit scenes need more.
_EMISSION_SPP, _LIT_SPP = 144, 256
#: Shapes an object can be.
OBJECT_KINDS = ("plane", "box", "sphere", "cylinder")
#: Cameras drawn (the paper's, with their lenses) and the focus-distance range of each, metres.
CAMERA_FOCUS_RANGES_M: Mapping[str, tuple[float, float]] = MappingProxyType({
    "canon_1d_mark_ii_85mm": (1.5, 4.0),
    "nikon_d50_180mm": (4.0, 12.0),
    "powershot_a80_7_8mm": (0.3, 0.8),
})
#: Probability of each camera, in the order of :data:`CAMERA_FOCUS_RANGES_M` (the paper's Figs. 5–7
#: camera first).
_CAMERA_WEIGHTS = (0.5, 0.25, 0.25)
#: Signed CoC (px, full preset, f/2) of the first object, always in front: σ_gt ≈ 9–16 px at f/2.
NEAR_COC_PX = (36.0, 64.0)
#: Largest |CoC| (px, full preset, f/2) of the other objects in front of the subject.
_MAX_FRONT_COC_PX = 64.0
#: Reference f-number of the defocus draw (its image width: :data:`scenes.library.base.REF_WIDTH_PX`).
REF_F_NUMBER = 2.0
#: Texture families and their probabilities (dead leaves and photos most often, as in natural images).
_FAMILY_WEIGHTS = MappingProxyType({"dead_leaves": 0.25, "photo": 0.15, "checker": 0.08, "stripes": 0.08,
                                    "text": 0.1, "brick": 0.1, "flat_patches": 0.12, "shading": 0.12})
#: Domain tag of the seed sequence (another generator of this project drawing from the same seed
#: gets other numbers).
_DOMAIN = 0x5EED_0F0C


@dataclasses.dataclass(frozen=True)
class SeedSplit:
    """A named range of scene seeds [start, stop).

    Attributes
    ----------
    name : str
    start, stop : int
        Seeds ``start <= s < stop``.
    purpose : str
        What the split is for.
    drawn : bool
        True when an evaluation draws its seeds at run time inside the range (``fresh``).
    """

    name: str
    start: int
    stop: int
    purpose: str
    drawn: bool = False

    def __contains__(self, seed) -> bool:
        return self.start <= int(seed) < self.stop


#: The seed splits: disjoint ranges. Tune on ``dev``; report ``test`` and ``fresh``.
SPLITS: Mapping[str, SeedSplit] = MappingProxyType({
    "dev": SeedSplit("dev", 0, 100_000, "tuning: look at these scenes, choose parameters on them"),
    "test": SeedSplit("test", 100_000, 200_000, "reporting: never tune on them"),
    "fresh": SeedSplit("fresh", 1_000_000, 2**31, "reporting on scenes nobody has seen: seeds drawn at run time",
                       drawn=True),
})


def _check_split(split) -> SeedSplit:
    if not isinstance(split, str) or split not in SPLITS:
        raise ValueError(f"split={split!r} is invalid (unknown split); allowed: {', '.join(SPLITS)}")
    return SPLITS[split]


def split_of(seed: int) -> str | None:
    """The split holding ``seed`` (None if none does)."""
    return next((s.name for s in SPLITS.values() if seed in s), None)


def check_seed_range(split: str, start: int, n: int) -> range:
    """The seeds ``start … start + n − 1`` after checking that they all lie in ``split``.

    Raises
    ------
    ValueError
        Unknown split, n ≤ 0, or a range reaching outside the split (e.g. into another split's seeds).
    """
    s = _check_split(split)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n <= 0:
        raise ValueError(f"N={n!r} is invalid; allowed: an integer number of scenes > 0")
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)):
        raise ValueError(f"scene seed start {start!r} is invalid; allowed: an integer")
    start, stop = int(start), int(start) + int(n)
    if start < s.start or stop > s.stop:
        other = [o.name for o in SPLITS.values() if o.name != s.name and start < o.stop and o.start < stop]
        where = f" (overlaps the {', '.join(other)} split)" if other else ""
        raise ValueError(f"scene seeds {start}..{stop - 1} are invalid for split {s.name!r}{where}; "
                         f"allowed: seeds in [{s.start}, {s.stop}) ({s.stop - s.start} seeds)")
    return range(start, stop)


def draw_fresh_start(n: int) -> int:
    """A start seed for ``n`` fresh scenes, drawn from the operating system's entropy.

    The seeds ``start … start + n − 1`` lie in the ``fresh`` split; record ``start`` to rerun them.
    """
    s = SPLITS["fresh"]
    check_seed_range("fresh", s.start, n)
    return s.start + secrets.randbelow(s.stop - s.start - int(n) + 1)


def procedural_name(seed: int, camera: str | None = None) -> str:
    """``procedural_<seed>`` (``procedural_<seed>_<camera>`` when the camera is forced)."""
    return f"{PROCEDURAL_PREFIX}_{int(seed)}" + (f"_{camera}" if camera else "")


_NAME = re.compile(rf"^{PROCEDURAL_PREFIX}_(\d+)(?:_([a-z0-9_]+))?$")


def is_procedural_name(name) -> bool:
    """Whether ``name`` names a procedural scene (``procedural_<seed>[_<camera>]``)."""
    return isinstance(name, str) and _NAME.match(name) is not None


def seed_of(name: str) -> tuple[int, str | None]:
    """(seed, forced camera or None) of a procedural scene name; ValueError for another name."""
    m = _NAME.match(name) if isinstance(name, str) else None
    if m is None:
        raise ValueError(f"{name!r} is not a procedural scene name; allowed: {PROCEDURAL_PREFIX}_<seed>[_<camera>]")
    return int(m.group(1)), m.group(2)


# --- the draw ---------------------------------------------------------------------------------------
def _coc_scale_px(camera_name: str, focus_m: float) -> float:
    """K (px·m): CoC diameter c(z) = K·|1/D − 1/z| at f/2 and 640 px width (Eq. 5 over the pixel pitch)."""
    cam = PAPER_CAMERAS[camera_name]
    f = cam.focal_length_m
    pitch = cam.sensor_width_m / REF_WIDTH_PX
    return f * f * focus_m / (REF_F_NUMBER * (focus_m - f)) / pitch


def _family(gen) -> str:
    names = list(_FAMILY_WEIGHTS)
    p = np.array([_FAMILY_WEIGHTS[n] for n in names])
    return str(names[int(gen.choice(len(names), p=p / p.sum()))])


def _object(gen, kind: str, *, coc_px: float, k_px: float, focus_m: float, centre_uv, size_frac) -> dict:
    z = 1.0 / (1.0 / focus_m - coc_px / k_px)  # c > 0 behind the focus plane, c < 0 in front
    obj = {"kind": kind, "coc_f2_px": float(coc_px), "depth_m": float(z), "u": float(centre_uv[0]),
           "v": float(centre_uv[1]), "size_frac": float(size_frac), "family": _family(gen),
           "texels_per_px": float(gen.uniform(1.0, 1.6)), "glossy": bool(gen.random() < 0.35),
           "roughness": float(gen.uniform(0.04, 0.25))}
    if kind == "plane":
        obj.update(aspect=float(gen.uniform(0.5, 2.0)), roll_deg=float(gen.uniform(-45, 45)),
                   tilt_x_deg=float(gen.uniform(-50, 50)) if gen.random() < 0.5 else 0.0,
                   tilt_y_deg=float(gen.uniform(-50, 50)) if gen.random() < 0.5 else 0.0)
    elif kind == "box":
        axis = gen.normal(size=3)
        obj.update(scale=[float(x) for x in gen.uniform(0.5, 1.0, 3)], axis=[float(x) for x in axis / np.linalg.norm(axis)],
                   angle_deg=float(gen.uniform(0, 360)))
    elif kind == "cylinder":
        obj.update(angle_deg=float(gen.uniform(0, 180)), tilt_deg=float(gen.uniform(-30, 30)),
                   radius_frac=float(gen.uniform(0.15, 0.4)))
    return obj


def _image_position(gen, *, avoid_centre: bool):
    """(u, v) in [−1, 1]²; away from the subject's box |u| < 0.35, |v| < 0.4 when asked."""
    while True:
        u, v = gen.uniform(-1.0, 1.0, 2)
        if not avoid_centre or abs(u) > 0.45 or abs(v) > 0.5:
            return float(u), float(v)


def draw_layout(seed: int, *, camera: str | None = None) -> dict:
    """The scene drawn from ``seed``: camera, focus, lighting, subject, objects, background (JSON-able).

    Parameters
    ----------
    seed : int
        Scene seed ≥ 0.
    camera : str, optional, keyword-only
        A key of :data:`scenes.camera.PAPER_CAMERAS` to use instead of the drawn one (the rest of the
        draw is the same; depths follow the camera's own defocus scale).

    Returns
    -------
    dict
        ``seed``, ``camera_name``, ``focus_distance_m``, ``lighting`` (a :data:`LIGHTING_KINDS` name),
        ``coc_scale_px_m`` (K of the module docstring), ``subject`` and ``objects`` (dicts: ``kind``,
        ``depth_m``, ``coc_f2_px``, image centre ``u``/``v``, ``size_frac``, texture ``family``, shape
        parameters), ``background`` (``depth_m``, ``family``, ``floor``: None or its height and family),
        ``light`` (lit scenes: position and size factors).

    Notes
    -----
    1. Camera (weights :data:`_CAMERA_WEIGHTS`) and focus distance D (log-uniform in its range);
       lighting ``lit`` with probability :data:`LIT_SHARE`.
    2. Background depth D·U(2.5, 10) (log-uniform), so its CoC c_bg is 60–90 % of the CoC at infinity.
    3. n ~ U{3 … 12} objects: the first at a CoC in :data:`NEAR_COC_PX` in front of the subject, the
       second behind it, the others in front (|c| log-uniform in [1, 64] px) or behind (c uniform in
       (0.05, 0.95)·c_bg) with equal odds; depth from c; objects in front avoid the subject's box.
    4. Texture family, shape parameters and material (glossy, roughness) per surface.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r} is invalid; allowed: an integer >= 0")
    gen = np.random.default_rng(np.random.SeedSequence([int(seed), _DOMAIN]))
    names = list(CAMERA_FOCUS_RANGES_M)
    drawn_camera = names[int(gen.choice(len(names), p=np.asarray(_CAMERA_WEIGHTS)))]
    if camera is not None and camera not in CAMERA_FOCUS_RANGES_M:
        raise ValueError(f"camera={camera!r} is invalid; allowed: {', '.join(CAMERA_FOCUS_RANGES_M)}")
    cam = camera or drawn_camera
    lo, hi = CAMERA_FOCUS_RANGES_M[cam]
    focus = float(math.exp(gen.uniform(math.log(lo), math.log(hi))))
    lighting = "lit" if gen.random() < LIT_SHARE else "emission"
    k = _coc_scale_px(cam, focus)
    bg_depth = focus * float(math.exp(gen.uniform(math.log(2.5), math.log(10.0))))
    c_bg = k * (1.0 / focus - 1.0 / bg_depth)
    floor = None
    if gen.random() < 0.6:
        floor = {"below_frac": float(gen.uniform(0.35, 0.9)), "family": _family(gen),
                 "texels_per_px": float(gen.uniform(1.0, 1.6))}
    subject_kind = str(gen.choice(["plane", "box", "sphere", "cylinder"]))
    subject = _object(gen, subject_kind, coc_px=0.0, k_px=k, focus_m=focus,
                      centre_uv=gen.uniform(-0.3, 0.3, 2), size_frac=gen.uniform(0.25, 0.4))
    subject["glossy"] = bool(lighting == "lit" and gen.random() < 0.6)
    if subject_kind == "plane":
        subject.update(tilt_x_deg=0.0, tilt_y_deg=0.0)  # a fronto-parallel card at exactly D
    n = int(gen.integers(3, 13))
    objects = []
    for i in range(n):
        if i == 0:
            c = -float(gen.uniform(*NEAR_COC_PX))
        elif i == 1 or gen.random() < 0.5:
            c = float(gen.uniform(0.05, 0.95)) * c_bg
        else:
            c = -float(math.exp(gen.uniform(0.0, math.log(_MAX_FRONT_COC_PX))))
        kind = str(gen.choice(OBJECT_KINDS))
        size = gen.uniform(0.15, 0.35) if i == 0 else gen.uniform(0.06, 0.25)
        uv = _image_position(gen, avoid_centre=c < 0)
        if i == 0:  # keep the nearest object in the frame: its centre within the inner 80 %
            uv = (float(np.clip(uv[0], -0.8, 0.8)), float(np.clip(uv[1], -0.8, 0.8)))
        objects.append(_object(gen, kind, coc_px=c, k_px=k, focus_m=focus, centre_uv=uv, size_frac=size))
    background = {"depth_m": bg_depth, "coc_f2_px": float(c_bg), "family": _family(gen),
                  "texels_per_px": float(gen.uniform(1.0, 1.6)), "floor": floor}
    light = None
    if lighting == "lit":
        light = {"side": float(gen.choice([-1.0, 1.0])), "height_frac": float(gen.uniform(0.8, 1.6)),
                 "size_frac": float(gen.uniform(0.3, 0.8)), "ambient": float(gen.uniform(0.03, 0.08))}
    return {"seed": int(seed), "camera_name": cam, "focus_distance_m": focus, "lighting": lighting,
            "coc_scale_px_m": float(k), "subject": subject, "objects": objects, "background": background,
            "light": light}


@dataclasses.dataclass(frozen=True)
class _ProceduralShapes:
    """The shape builder of a procedural scene: draws the layout again and builds its shapes. A frozen
    dataclass, so its ``repr`` (part of the scene-hash memo key, :func:`scenes.render.scene_content_hash`)
    is the same in every process."""

    seed: int
    camera: str | None

    def __call__(self) -> dict:
        from .procedural_shapes import layout_shapes

        return layout_shapes(draw_layout(self.seed, camera=self.camera))


def procedural_scene(seed: int, *, camera: str | None = None) -> SceneDefinition:
    """The procedural scene of ``seed`` (the same object for the same arguments within a process).

    Parameters
    ----------
    seed : int
        Scene seed ≥ 0 (:data:`SPLITS` says which seeds are for tuning and which for reporting).
    camera : str, optional, keyword-only
        Force one of :data:`scenes.camera.PAPER_CAMERAS` (default: drawn from the seed).

    Returns
    -------
    SceneDefinition
        Named :func:`procedural_name`; ``facts`` holds the layout (:func:`draw_layout`) and the split.
        The same object for the same seed and camera (cached), as :func:`scenes.render.scene_content_hash`
        needs to memoise the scene's hash.

    Raises
    ------
    ValueError
        A negative or non-integer seed, an unknown camera.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r} is invalid; allowed: an integer >= 0")
    return _procedural_scene(int(seed), camera)


@functools.lru_cache(maxsize=4096)
def _procedural_scene(seed: int, camera: str | None) -> SceneDefinition:
    layout = draw_layout(seed, camera=camera)
    kinds = [layout["subject"]["kind"], *(o["kind"] for o in layout["objects"])]
    desc = (f"procedural seed {seed}: {layout['lighting']}, {layout['camera_name']} focused at "
            f"{layout['focus_distance_m']:.2f} m, subject {kinds[0]}, {len(kinds) - 1} objects at "
            f"{min(o['depth_m'] for o in layout['objects']):.2f}-{max(o['depth_m'] for o in layout['objects']):.2f} m, "
            f"background at {layout['background']['depth_m']:.1f} m")
    lit = layout["lighting"] == "lit"
    return SceneDefinition(
        name=procedural_name(seed, camera),
        version=1,
        description=desc,
        focus_distance_m=layout["focus_distance_m"],
        shapes=_ProceduralShapes(int(seed), camera),
        integrator=PATH_INTEGRATOR if lit else EMISSION_ONLY_INTEGRATOR,
        default_spp=spp_per_preset(_LIT_SPP if lit else _EMISSION_SPP),
        camera_name=layout["camera_name"],
        facts=MappingProxyType({"layout": layout, "split": split_of(seed), "lighting": layout["lighting"]}),
    )
