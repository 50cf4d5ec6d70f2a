"""One image check (method.validation) behind every entry point: same arrays rejected, same messages."""

import numpy as np
import pytest

from method import DefocusParams, biased_cross_bilateral, estimate_defocus_map
from method.validation import validate_image, validate_sparse_sigma

BAD_IMAGES = [
    ("float array", [[0.5] * 16] * 16),
    ("dtype", np.full((16, 16, 3), 128, dtype=np.uint8)),
    ("NaN", np.where(np.eye(16)[..., None] > 0, np.nan, 0.5) * np.ones((1, 1, 3))),
    ("[0, 1]", np.full((16, 16, 3), 1.5)),
    ("shape", np.zeros((16, 16, 4))),
]


@pytest.mark.parametrize("what,image", BAD_IMAGES, ids=[b[0] for b in BAD_IMAGES])
def test_pipeline_and_cross_bilateral_reject_the_same_images(what, image):
    with pytest.raises(ValueError) as direct:
        validate_image(image, name="reference", min_side=1)
    with pytest.raises(ValueError) as cbf:
        biased_cross_bilateral(np.full((16, 16), np.nan), image)
    assert str(cbf.value) == str(direct.value)
    with pytest.raises(ValueError) as pipe:
        estimate_defocus_map(image, DefocusParams())
    assert str(pipe.value) == str(direct.value).replace("reference", "image")


def test_validate_image_accepts_and_clips_round_off():
    img = np.full((8, 8, 3), 0.5)
    img[0, 0, 0] = 1 + 1e-7
    out = validate_image(img)
    assert out.dtype == np.float64 and out.max() == 1.0
    with pytest.raises(ValueError, match="smallest supported side is 8"):
        validate_image(np.zeros((7, 9)))
    assert validate_image(np.zeros((2, 2)), min_side=2).shape == (2, 2)
    with pytest.raises(ValueError, match="HxW or HxWx3"):
        validate_image(np.zeros((8, 8, 1)))
    assert validate_image(np.zeros((8, 8, 1)), channels=(1, 3)).shape == (8, 8, 1)


def test_validate_sparse_sigma():
    good = np.full((4, 5), np.nan)
    good[1, 1] = 2.0
    assert validate_sparse_sigma(good, (4, 5, 3)).dtype == np.float64
    for bad, msg in ((np.zeros((4, 4)), "shape"), (np.zeros((4, 5), int), "float"),
                     (np.full((4, 5), np.inf), "Inf"), (np.full((4, 5), -1.0), ">= 0")):
        with pytest.raises(ValueError, match=msg):
            validate_sparse_sigma(bad, (4, 5))
        with pytest.raises(ValueError, match=msg):
            biased_cross_bilateral(bad, np.zeros((4, 5, 3)))
