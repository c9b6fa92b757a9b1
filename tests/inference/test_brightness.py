"""The brightness tie: the output's low-pass brightness in linear light becomes the input's,
detail finer than the low-pass is kept, colours keep their ratios, and the option reaches every
way of deblurring."""

import cv2
import numpy as np
import pytest

import dualpixel
from dualpixel.errors import ParameterError
from dualpixel.inference import Deblurrer
from dualpixel.inference.brightness import tie_brightness
from dualpixel.optics.tone import linear_to_srgb_array as encoded
from dualpixel.optics.tone import srgb_to_linear_array as linear


@pytest.fixture(scope="module")
def views():
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.standard_normal((160, 240, 3)).astype(np.float32), (0, 0), 2)
    left = np.clip(0.45 + 0.8 * texture, 0.02, 0.95)
    right = np.roll(left, 2, axis=1)
    return left, right


def test_a_gain_in_linear_light_is_undone_and_detail_kept(views):
    left, right = views
    mean = 0.5 * (linear(left) + linear(right))
    # a "deblurred" output: detail added in linear light, which keeps the low-pass brightness
    sharp = encoded(np.clip(mean + 0.5 * (mean - cv2.GaussianBlur(mean, (0, 0), 2.0)), 0, 1))
    darker = encoded(linear(sharp) * 0.9)
    tied = tie_brightness(darker, left, right, sigma=32)
    assert linear(tied).mean() == pytest.approx(mean.mean(), rel=0.003)
    # the detail the "network" added is back where it was, not smoothed away
    assert np.abs(tied - sharp).mean() < 0.1 * np.abs(darker - sharp).mean()
    # one gain per pixel for all channels: colour ratios in linear light are kept
    before, after = linear(darker), linear(tied)
    unclipped = (after < 0.99).all(axis=2) & (before > 0.01).all(axis=2) & (after > 0.01).all(
        axis=2)
    np.testing.assert_allclose(after[unclipped][:, 0] / after[unclipped][:, 1],
                               before[unclipped][:, 0] / before[unclipped][:, 1], rtol=1e-3)


def test_grey_raw_views_are_tied_in_linear_light_like_colour_ones(views):
    """A phone's green-only raw views made display values for the model (grey, copied to R, G
    and B; finer than 8 bits) hold few distinct 8-bit colours, as a GIF frame does, but carry
    no palette dither: the tie measures them as they are, so a sharp output keeps the input's
    light."""
    left, right = (np.repeat(np.rint(v.mean(axis=2, keepdims=True) * 65535) / 65535, 3, axis=2)
                   for v in views)
    mean = 0.5 * (linear(left) + linear(right))
    sharp = encoded(np.clip(mean + 1.5 * (mean - cv2.GaussianBlur(mean, (0, 0), 2.0)), 0, 1))
    tied = tie_brightness(sharp, left, right, sigma=32)
    assert linear(tied).mean() == pytest.approx(mean.mean(), rel=0.002)


def test_only_images_on_the_8_bit_grid_with_few_colours_are_palette_images(views):
    from dualpixel.inference.brightness import is_palette_image

    rng = np.random.default_rng(3)
    palette = rng.integers(0, 256, (200, 3)) / 255.0
    gif = palette[rng.integers(0, 200, (60, 80))].astype(np.float32)  # 200 colours, dithered
    assert is_palette_image(gif)
    assert not is_palette_image(gif + 0.5 / 65535)  # 16-bit values: no GIF frame
    assert not is_palette_image(views[0])  # a photograph's many colours
    grey = np.repeat(gif[..., 1:2], 3, axis=2)  # an 8-bit grey GIF frame: dithered greys
    assert is_palette_image(grey) and is_palette_image(gif[..., 1:2])
    assert not is_palette_image(grey + 0.5 / 65535)  # raw greys, finer than 8 bits


def test_an_output_that_keeps_brightness_is_left_alone(views):
    left, right = views
    mean = encoded(0.5 * (linear(left) + linear(right)))
    np.testing.assert_allclose(tie_brightness(mean, left, right), mean, atol=2e-3)


def test_bad_settings_are_refused(views, refined_model):
    with pytest.raises(ParameterError, match="sigma"):
        tie_brightness(views[0], *views, sigma=0)
    with pytest.raises(ParameterError, match="brightness"):
        Deblurrer(refined_model, brightness="bright")


def test_the_option_reaches_the_deblurrer_and_the_api(views, refined_model):
    left, right = views
    plain = Deblurrer(refined_model, precision="fp32", brightness="model")(left, right)
    tied = Deblurrer(refined_model, precision="fp32", brightness="tied")(left, right)
    np.testing.assert_allclose(tied, tie_brightness(plain, left, right), atol=1e-6)
    api = dualpixel.deblur(left, right, model=refined_model, device="cpu", precision="fp32",
                           brightness="tied")
    np.testing.assert_allclose(api, tied, atol=1e-6)
