"""The tiled magnifier passes ``in_front`` on per tile, cut to each tile."""

from __future__ import annotations

import numpy as np

from method.magnify.magnification import magnify_defocus
from method.magnify.upsampling import magnify_defocus_tiled


def test_tiled_scatter_with_in_front_equals_whole_image():
    rng = np.random.default_rng(5)
    h, w = 300, 280
    img = rng.random((h, w, 3))
    m = 3.0 * np.linspace(0.0, 1.0, w)[None, :] * np.ones((h, 1))
    in_front = np.zeros((h, w), bool)
    in_front[:, 200:] = True  # a blurry foreground on the right
    whole = magnify_defocus(img, m, factor=2.0, renderer="scatter", preprocess=False, in_front=in_front)
    tiled = magnify_defocus_tiled(img, m, factor=2.0, renderer="scatter", preprocess=False, tile_pixels=256 * 256,
                                  in_front=in_front)
    np.testing.assert_allclose(tiled, whole, rtol=0, atol=1e-6)
    without = magnify_defocus(img, m, factor=2.0, renderer="scatter", preprocess=False)
    assert np.abs(whole - without).max() > 1e-3  # in_front changes the result, so the comparison above is not empty
