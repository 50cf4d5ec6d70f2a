"""The 8× coarse-grid path of the propagation: what the photo tools' 1.5 MP working size uses."""

import numpy as np
import pytest

from method import DefocusParams, estimate_defocus_map
from method.propagation.defocus import AUTO_MAX_COARSE_PIXELS, _auto_downsample, propagate_defocus
from method.magnify.upsampling import DEFAULT_MAX_WORKING_PIXELS, working_shape


@pytest.mark.parametrize("photo_shape", [(2000, 3000, 3), (1000, 1500, 3), (3456, 5184, 3)])
def test_photo_tools_working_size_is_solved_8x_coarser(photo_shape):
    (h, w), _scale = working_shape(photo_shape, max_working_pixels=DEFAULT_MAX_WORKING_PIXELS)
    assert 1.2e6 < h * w <= DEFAULT_MAX_WORKING_PIXELS
    assert _auto_downsample(h, w, AUTO_MAX_COARSE_PIXELS) == 8  # the README's stated factors: 4, 8, 16
    assert _auto_downsample(512, 512, AUTO_MAX_COARSE_PIXELS) == 8  # 4× only up to a 2^13 px coarse grid
    assert _auto_downsample(1024, 1024, AUTO_MAX_COARSE_PIXELS) == 8  # 1 MP too (the 2^15 px coarse budget)


@pytest.fixture(scope="module")
def measures():
    from skimage import data, transform

    img = transform.resize(data.astronaut(), (256, 256), anti_aliasing=True)
    return estimate_defocus_map(img, DefocusParams()).refined_sigma, img


def test_8x_coarse_solve_is_close_to_the_exact_solve(measures):
    sparse, img = measures
    exact = propagate_defocus(sparse, img, downsample=1)
    coarse8 = propagate_defocus(sparse, img, downsample=8)
    err = np.abs(coarse8 - exact)
    # measured 0.005 px RMS, 0.023 px p99 on this image (mean σ 0.72 px)
    assert np.sqrt(np.mean(err**2)) < 0.03 and np.percentile(err, 99) < 0.1
    assert not np.array_equal(coarse8, exact)  # it really is a different (approximate) path
    # "auto" takes the same 8× path when the coarse budget asks for it
    auto = propagate_defocus(sparse, img, max_coarse_pixels=32 * 32)
    np.testing.assert_array_equal(auto, coarse8)
