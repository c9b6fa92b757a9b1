"""The gradient used for flat-patch rejection and figure crops."""

import numpy as np
import pytest
from scipy import ndimage

from dualpixel.filters import gradient_magnitude, sharpness


def test_gradient_is_the_reflect_bordered_sobel_magnitude_of_the_grey_image():
    image = np.random.default_rng(0).random((37, 53, 3)).astype(np.float32)
    grey = image.mean(axis=-1)
    expected = np.hypot(ndimage.sobel(grey, 0), ndimage.sobel(grey, 1))  # mode="reflect"
    np.testing.assert_allclose(gradient_magnitude(image), expected, atol=1e-5)
    ramp = np.repeat(np.linspace(0, 1, 11, dtype=np.float32)[None, :, None], 3, axis=2)
    ramp = np.repeat(ramp, 6, axis=0)  # +0.1 per column; unnormalised Sobel: 0.2 x (1 + 2 + 1)
    assert gradient_magnitude(ramp)[2:-2, 1:-1] == pytest.approx(0.8)


def test_8_bit_images_are_read_in_unit_range():
    image = np.random.default_rng(1).integers(0, 256, (20, 30, 3), dtype=np.uint8)
    assert sharpness(image) == pytest.approx(sharpness(image / 255.0), rel=1e-5)
    assert sharpness(np.full((8, 8, 3), 200, np.uint8)) == 0.0
