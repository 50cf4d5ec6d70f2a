"""A render's file: :class:`Render` (the image and its per-pixel ground truth), written as one float32
EXR (:mod:`scenes.exr`) plus a JSON sidecar and read back (:func:`load_render`).

Renders are made by :func:`scenes.render.render_scene`; the names here are also importable from
:mod:`scenes.render`.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from defocus_cache import atomic_write_text

from .camera import ThinLensCamera
from .display import camera_image
from .exr import read_exr, write_exr

__all__ = ["EXR_NAME", "Render", "load_render", "sidecar_path"]

#: File names inside a cache entry.
EXR_NAME = "render.exr"

_CHANNELS = {"rgb": "RGB", "depth": "Z", "coc_px": "coc", "sigma_px": "sigma", "occlusion_boundary": "occlusion_boundary"}
CHANNEL_UNITS = {
    "RGB": "linear radiance (float32, unclamped)",
    "Z": "camera-space depth z, metres; inf = the pixel-centre lens-centre ray missed",
    "coc": "circle-of-confusion diameter, px (Eq. 5 / pixel pitch)",
    "sigma": "ground-truth Gaussian blur sigma, px (convention + box filter in quadrature)",
    "occlusion_boundary": "1 within a CoC radius + 1 px of a depth discontinuity, else 0",
}


@dataclasses.dataclass(frozen=True, eq=False)
class Render:
    """One rendered image with its per-pixel ground truth.

    Attributes
    ----------
    rgb : ndarray, HxWx3 float32
        Linear radiance (unclamped).
    depth : ndarray, HxW float32
        Camera-space depth z, metres (``inf`` where the pixel-centre ray missed).
    coc_px : ndarray, HxW float32
        Circle-of-confusion diameter, px, Eq. (5).
    sigma_px : ndarray, HxW float32
        σ_gt, px; convention in ``metadata["sigma_convention"]``.
    occlusion_boundary : ndarray, HxW bool
        Pixels within a CoC radius of a depth discontinuity (mixed blur; see
        :func:`scenes.ground_truth.occlusion_boundary_mask`).
    metadata : dict
        The JSON sidecar: scene, version, camera, resolution, spp, seed, variant, versions, timings.
    path : Path or None
        The EXR file (None for an uncached in-memory render).
    """

    rgb: np.ndarray
    depth: np.ndarray
    coc_px: np.ndarray
    sigma_px: np.ndarray
    occlusion_boundary: np.ndarray
    metadata: dict
    path: Path | None = None

    def image(self, *, encoding="srgb", exposure=1.0, quantize_bits=None, noise="none", jpeg_quality=None,
              rng=None) -> np.ndarray:
        """The image the method sees (:func:`scenes.display.camera_image`).

        Parameters
        ----------
        encoding : {"srgb", "linear"}, keyword-only
        exposure : float, keyword-only
            Multiplier on the linear radiance before clipping to [0, 1].
        quantize_bits : int or None, keyword-only
            Round to this many bits per channel (8 for a JPEG-like input).
        noise : str or (float, float), keyword-only
            Sensor noise level: a name of :data:`scenes.display.NOISE_LEVELS` ("none", "iso100",
            "iso800", "iso3200") or the variances (a, b) of a linear signal.
        jpeg_quality : int or None, keyword-only
            JPEG quality 1–100 applied last (8 bits); None: no JPEG.
        rng : numpy.random.Generator or int or None, keyword-only
            The noise's generator or seed (None: seed 0): the same seed gives the same noise.

        Returns
        -------
        ndarray, HxWx3 float64 in [0, 1]
        """
        return camera_image(self.rgb, exposure=exposure, quantize_bits=quantize_bits, encoding=encoding, noise=noise,
                            jpeg_quality=jpeg_quality, rng=rng)

    @property
    def camera(self) -> ThinLensCamera:
        """The camera that rendered this image."""
        d = dict(self.metadata["camera"])
        fields = {f.name for f in dataclasses.fields(ThinLensCamera)}
        return ThinLensCamera(**{k: (tuple(v) if k == "resolution" else v) for k, v in d.items() if k in fields})

    @property
    def in_front(self) -> np.ndarray:
        """Pixels nearer than the focus plane, HxW bool: depth z < the camera's focus distance D (metres).

        The pixels a scatter renderer must let spread over what is behind them
        (:func:`method.magnify.scatter.layer_index`); False where the ray missed (z = inf).
        """
        return np.asarray(self.depth, dtype=np.float64) < self.camera.focus_distance_m

    def save(self, path) -> Path:
        """Write the EXR and its JSON sidecar (``path`` with suffix ``.json``), atomically.

        Parameters
        ----------
        path : str or Path
            Destination ``.exr``; its folder must exist.

        Returns
        -------
        Path
            The EXR path.
        """
        path = Path(path)
        write_exr(path, {_CHANNELS[k]: getattr(self, k) for k in _CHANNELS})
        atomic_write_text(sidecar_path(path), json.dumps(self.metadata, indent=1, sort_keys=True, default=_json_default))
        return path


def sidecar_path(exr_path) -> Path:
    """The JSON sidecar next to an EXR file (same name, suffix ``.json``)."""
    return Path(exr_path).with_suffix(".json")


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)


def load_render(path) -> Render:
    """Read a render written by :func:`render_scene` or :meth:`Render.save`.

    Parameters
    ----------
    path : str or Path
        The EXR file, or a cache-entry folder holding ``render.exr``.

    Returns
    -------
    Render

    Raises
    ------
    FileNotFoundError
        If the EXR or its sidecar is missing.
    ValueError
        If a ground-truth channel is missing.
    """
    path = Path(path)
    if path.is_dir():
        path = path / EXR_NAME
    channels = read_exr(path)
    missing = [c for c in _CHANNELS.values() if c not in channels]
    if missing:
        raise ValueError(f"{path} lacks channels {missing}; has {sorted(channels)}")
    side = sidecar_path(path)
    if not side.is_file():
        raise FileNotFoundError(f"no JSON sidecar next to {path}: {side}")
    metadata = json.loads(side.read_text())
    return Render(
        rgb=channels["RGB"],
        depth=channels["Z"],
        coc_px=channels["coc"],
        sigma_px=channels["sigma"],
        occlusion_boundary=channels["occlusion_boundary"] > 0.5,
        metadata=metadata,
        path=path,
    )
