"""The tiled magnifier passes the per-pixel options on per tile: ``in_front`` and any HxW subject array cut to
each tile, ``focus_point`` moved into the tile's coordinates."""

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


def test_subject_options_are_cut_to_each_tile(monkeypatch):
    import method.magnify.magnification as magnification

    calls = []

    def fake(image, defocus_map, *, focus_point=None, keep_sharp=None, **kwargs):
        calls.append((focus_point, keep_sharp))
        return magnify_defocus(image, defocus_map, **kwargs)

    monkeypatch.setattr(magnification, "magnify_defocus", fake)
    h, w = 300, 280
    index = np.arange(h * w, dtype=float).reshape(h, w)  # each pixel's own number
    magnify_defocus_tiled(np.zeros((h, w, 3)), np.ones((h, w)), factor=2.0, renderer="gather", preprocess=False,
                          tile_pixels=256 * 256, focus_point=(250, 10), keep_sharp=index)
    assert len(calls) > 1
    for point, cut in calls:
        y0, x0 = divmod(int(cut[0, 0]), w)   # where the tile starts in the photo
        assert point == (250 - x0, 10 - y0)
        np.testing.assert_array_equal(cut, index[y0:y0 + cut.shape[0], x0:x0 + cut.shape[1]])
