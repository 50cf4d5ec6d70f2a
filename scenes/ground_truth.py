"""Per-pixel ground truth of a render: camera-space depth, CoC (Eq. 5), σ_gt, occlusion boundaries.

Depth is *not* taken from a depth AOV (that is the ray length from the near-clip plane, averaged over
the pixel filter and the lens). Following RENDERING-FACTS.md, for every pixel centre we cast the
lens-centre ray ``sensor.sample_ray(0, 0.5, ((x+.5)/W, (y+.5)/H), (0.5, 0.5))``, intersect it with
the scene and take z = (p − camera position)·forward, measured from the camera's position (not from
``ray.o``, which Mitsuba moves to the near-clip plane). Misses get z = inf.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .thin_lens import BOX_FILTER_SIGMA_PX, coc_to_sigma

__all__ = [
    "OCCLUSION_MARGIN_PX",
    "OCCLUSION_REL_JUMP",
    "camera_space_depth",
    "depth_discontinuities",
    "ground_truth_from_depth",
    "occlusion_boundary_mask",
]

#: Relative depth jump between 4-neighbours, beyond what the neighbouring steps explain, that counts
#: as a depth discontinuity (5 %); see :func:`depth_discontinuities`.
OCCLUSION_REL_JUMP = 0.05
#: Extra dilation (px) beyond the CoC radius, covering the pixel filter and the half-pixel offset.
OCCLUSION_MARGIN_PX = 1.0


def _camera_frame(mi, sensor):
    """Camera position and forward unit vector (world space) from the sensor's to_world."""
    import drjit as dr

    tf = sensor.world_transform()
    o = tf @ mi.Point3f(0.0, 0.0, 0.0)
    f = dr.normalize(tf @ mi.Vector3f(0.0, 0.0, 1.0))

    def first(v):  # a Python float (scalar variants) or a width-1 Dr.Jit array (JIT variants)
        return float(np.ravel(np.asarray(v, dtype=np.float64))[0])

    pos = np.array([first(o.x), first(o.y), first(o.z)])
    fwd = np.array([first(f.x), first(f.y), first(f.z)])
    return pos, fwd


def camera_space_depth(scene, *, mi=None) -> np.ndarray:
    """Camera-space depth z of the surface seen through each pixel centre by the lens-centre ray.

    Parameters
    ----------
    scene : mitsuba.Scene
        A loaded scene whose first sensor is the camera (any variant; JIT variants are vectorised,
        ``scalar_*`` variants loop in Python, ~1 s per 20 000 pixels).
    mi : module, optional, keyword-only
        The ``mitsuba`` module with the variant set (imported if omitted).

    Returns
    -------
    ndarray, HxW float32
        z in metres along the camera's forward axis; ``inf`` where the ray hits nothing.
    """
    if mi is None:
        import mitsuba as mi

    sensor = scene.sensors()[0]
    width, height = (int(v) for v in sensor.film().crop_size())
    pos, fwd = _camera_frame(mi, sensor)
    ys, xs = np.mgrid[0:height, 0:width]
    u = ((xs.ravel() + 0.5) / width).astype(np.float32)
    v = ((ys.ravel() + 0.5) / height).astype(np.float32)
    if mi.variant().startswith("scalar"):
        z = np.empty(u.size, np.float64)
        for i in range(u.size):
            ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u[i], v[i]), mi.Point2f(0.5, 0.5))
            si = scene.ray_intersect(ray)
            if si.is_valid():
                p = np.array([si.p.x, si.p.y, si.p.z], dtype=np.float64)
                z[i] = (p - pos) @ fwd
            else:
                z[i] = np.inf
    else:
        ray, _ = sensor.sample_ray(
            0.0, 0.5, mi.Point2f(mi.Float(u), mi.Float(v)), mi.Point2f(mi.Float(0.5), mi.Float(0.5))
        )
        si = scene.ray_intersect(ray)
        valid = np.asarray(si.is_valid(), dtype=bool)
        p = np.stack([np.asarray(si.p.x), np.asarray(si.p.y), np.asarray(si.p.z)], axis=1).astype(np.float64)
        z = (p - pos) @ fwd
        z[~valid] = np.inf
    return z.reshape(height, width).astype(np.float32)


def _steps_along(w, axis):
    """Discontinuity flags of consecutive pairs of ``w`` (inverse depth) along ``axis``."""
    w = np.moveaxis(w, axis, -1)
    d = np.diff(w, axis=-1)                      # step between pixel i and i+1, (..., n-1)
    big = np.full(d.shape[:-1] + (1,), np.inf)
    prev = np.concatenate([big, d[..., :-1]], axis=-1)   # step i-1 → i (inf at the border)
    nxt = np.concatenate([d[..., 1:], big], axis=-1)     # step i+1 → i+2
    # Second difference on the smoother side: ~0 wherever the surface continues on either side
    # (1/z is affine across a plane), the full jump at a depth discontinuity.
    curv = np.minimum(np.abs(d - prev), np.abs(d - nxt))
    if d.shape[-1] == 1:
        curv = np.abs(d)
    # The jump itself is the largest step around: a flat step beside a jump is not flagged.
    nb = np.maximum(np.where(np.isinf(prev), 0.0, np.abs(prev)), np.where(np.isinf(nxt), 0.0, np.abs(nxt)))
    dominant = np.abs(d) >= 0.5 * nb
    wmax = np.maximum(w[..., :-1], w[..., 1:])
    return np.moveaxis(curv, -1, axis), np.moveaxis(wmax, -1, axis), np.moveaxis(dominant, -1, axis)


def depth_discontinuities(depth, *, rel_jump=OCCLUSION_REL_JUMP) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of 4-neighbour pixels across which depth jumps (occlusion boundaries).

    Parameters
    ----------
    depth : ndarray, HxW
        Camera-space depth in metres (``inf`` = miss; a miss next to a hit is a discontinuity).
    rel_jump : float, keyword-only
        Threshold on the relative jump, > 0 (see Notes).

    Returns
    -------
    (horizontal, vertical) : (ndarray Hx(W−1) bool, ndarray (H−1)xW bool)
        ``horizontal[y, x]`` flags the pair (x, x+1) of row y; ``vertical[y, x]`` the pair (y, y+1).

    Notes
    -----
    Works on inverse depth w = 1/z (0 for misses), which is affine in image coordinates across any
    plane. With Δᵢ = w[i+1] − w[i], a pair is a discontinuity when the step departs from the
    neighbouring step on *both* sides: min(|Δᵢ − Δᵢ₋₁|, |Δᵢ − Δᵢ₊₁|) > rel_jump · max(w[i], w[i+1]),
    i.e. a relative depth jump of more than ``rel_jump`` that a smooth surface does not explain, and
    |Δᵢ| ≥ ½·max(|Δᵢ₋₁|, |Δᵢ₊₁|) (the flat step beside a jump is not itself a jump).
    A plane seen at a grazing angle (large but steady steps) is therefore not flagged; a sliver
    one pixel wide is (its neighbour steps point the other way).
    """
    if not rel_jump > 0:
        raise ValueError(f"rel_jump={rel_jump!r} is invalid; allowed: > 0")
    z = np.asarray(depth, dtype=np.float64)
    if z.ndim != 2:
        raise ValueError(f"depth has shape {z.shape}; allowed: HxW")
    with np.errstate(divide="ignore"):
        w = np.where(np.isfinite(z) & (z > 0), 1.0 / z, 0.0)
    out = []
    for axis in (1, 0):
        if w.shape[axis] < 2:
            shape = list(w.shape)
            shape[axis] = max(shape[axis] - 1, 0)
            out.append(np.zeros(shape, dtype=bool))
            continue
        curv, wmax, dominant = _steps_along(w, axis)
        out.append((curv > rel_jump * wmax) & dominant)
    return out[0], out[1]


def occlusion_boundary_mask(depth, coc_px, *, rel_jump=OCCLUSION_REL_JUMP, margin_px=OCCLUSION_MARGIN_PX) -> np.ndarray:
    """Pixels within a CoC radius (plus a margin) of a depth discontinuity.

    There the rendered blur mixes two depths (and partial occlusion of the lens), so the per-pixel
    σ_gt from depth is not the blur the image shows; metrics exclude or report these pixels apart.

    Parameters
    ----------
    depth : ndarray, HxW
        Camera-space depth, metres.
    coc_px : ndarray, HxW
        CoC diameter in pixels (Eq. 5) for ``depth``.
    rel_jump : float, keyword-only
        See :func:`depth_discontinuities`.
    margin_px : float, keyword-only
        Added to the dilation radius, px, ≥ 0.

    Returns
    -------
    ndarray, HxW bool

    Notes
    -----
    1. Flag both pixels of every 4-neighbour pair across a depth discontinuity
       (:func:`depth_discontinuities`).
    2. Each flagged pair gets radius r = max(c₁, c₂)/2 + ``margin_px`` (the blurrier side's CoC
       radius: its blur spreads across the edge).
    3. Mark every pixel within Euclidean distance r of a flagged pixel (one distance transform per
       integer radius bucket, rounding r up).
    """
    z = np.asarray(depth, dtype=np.float64)
    c = np.asarray(coc_px, dtype=np.float64)
    if z.shape != c.shape or z.ndim != 2:
        raise ValueError(f"depth {z.shape} and coc_px {c.shape} must be equal HxW shapes")
    if margin_px < 0:
        raise ValueError(f"margin_px={margin_px!r} is invalid; allowed: >= 0")
    h_pairs, v_pairs = depth_discontinuities(z, rel_jump=rel_jump)
    radius = np.full(z.shape, -1.0)
    cc = np.where(np.isfinite(c), c, 0.0)
    rh = np.maximum(cc[:, :-1], cc[:, 1:]) / 2.0 + margin_px
    rv = np.maximum(cc[:-1, :], cc[1:, :]) / 2.0 + margin_px
    for sl_a, sl_b, pairs, r in (
        ((slice(None), slice(None, -1)), (slice(None), slice(1, None)), h_pairs, rh),
        ((slice(None, -1), slice(None)), (slice(1, None), slice(None)), v_pairs, rv),
    ):
        rr = np.where(pairs, r, -1.0)
        radius[sl_a] = np.maximum(radius[sl_a], rr)
        radius[sl_b] = np.maximum(radius[sl_b], rr)
    mask = np.zeros(z.shape, dtype=bool)
    seeds = radius >= 0
    if not seeds.any():
        return mask
    buckets = np.ceil(radius[seeds]).astype(int)
    for r in np.unique(buckets):
        seed_r = np.zeros(z.shape, dtype=bool)
        seed_r[seeds] = buckets == r
        dist = ndimage.distance_transform_edt(~seed_r)
        mask |= dist <= r
    return mask


def ground_truth_from_depth(
    depth, camera, *, sigma_convention="line_spread", filter_sigma_px=BOX_FILTER_SIGMA_PX
) -> dict[str, np.ndarray]:
    """CoC (Eq. 5), σ_gt and occlusion-boundary mask from camera-space depth.

    Parameters
    ----------
    depth : ndarray, HxW
        Camera-space depth z, metres (``inf`` = miss; gets the limit f²/(N(D − f)) of Eq. 5).
    camera : scenes.camera.ThinLensCamera
        The camera that rendered the image (its resolution must match ``depth``).
    sigma_convention : {"line_spread", "erf_fit"}, keyword-only
        CoC → σ convention (:data:`scenes.thin_lens.SIGMA_CONVENTIONS`).
    filter_sigma_px : float, keyword-only
        σ of the pixel reconstruction filter, px (box: 1/√12), combined in quadrature.

    Returns
    -------
    dict
        ``coc_px`` (HxW float32, CoC diameter in px, Eq. 5 / pixel pitch), ``sigma_px`` (HxW
        float32, σ_gt in px), ``occlusion_boundary`` (HxW bool).
    """
    z = np.asarray(depth, dtype=np.float64)
    w, h = camera.resolution
    if z.shape != (h, w):
        raise ValueError(f"depth has shape {z.shape}; the camera renders {(h, w)} (HxW)")
    coc = camera.coc_px(z)
    sigma = coc_to_sigma(coc, convention=sigma_convention, filter_sigma_px=filter_sigma_px)
    return {
        "coc_px": coc.astype(np.float32),
        "sigma_px": sigma.astype(np.float32),
        "occlusion_boundary": occlusion_boundary_mask(z, coc),
    }
