"""The sRGB transfer function (IEC 61966-2-1) and the raw storage of linear light."""

import numpy as np
import pytest
import torch

from dualpixel.optics.tone import linear_to_raw, linear_to_srgb, srgb_to_linear


def _iec_encode(linear: np.ndarray) -> np.ndarray:
    """The standard's piecewise definition, in float64."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _iec_decode(encoded: np.ndarray) -> np.ndarray:
    x = np.clip(encoded, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


# both segments, both thresholds and the clipped range outside [0, 1]
VALUES = np.concatenate([np.linspace(-0.2, 1.2, 20_001), [0.0031308, 0.04045, 0.0, 1.0]])


def test_curves_follow_the_standard_on_both_segments():
    values = torch.from_numpy(VALUES.astype(np.float32))
    exact = values.numpy().astype(np.float64)  # the same float32 numbers
    # within a few float32 steps of the float64 standard (one step near 1 is 6e-8)
    assert np.abs(linear_to_srgb(values).numpy() - _iec_encode(exact)).max() < 4e-7
    assert np.abs(srgb_to_linear(values).numpy() - _iec_decode(exact)).max() < 4e-7
    # known points: mid grey, the thresholds, the ends
    assert float(srgb_to_linear(torch.tensor(0.5))) == pytest.approx(0.214041, abs=1e-6)
    assert float(linear_to_srgb(torch.tensor(0.0031308))) == pytest.approx(0.04045, abs=1e-6)
    assert float(linear_to_srgb(torch.tensor(1.0))) == pytest.approx(1.0, abs=1e-6)


def test_curves_take_images_in_any_memory_layout():
    """(H, W, C) images seen as (C, H, W), slices and scalars give the standard's values."""
    image = torch.rand(40, 60, 3, generator=torch.Generator().manual_seed(1))
    for values in (image.permute(2, 0, 1), image[:, ::2], image[5, 7, 1]):
        exact = values.double().numpy()
        assert np.abs(linear_to_srgb(values).numpy() - _iec_encode(exact)).max() < 4e-7
        assert np.abs(srgb_to_linear(values).numpy() - _iec_decode(exact)).max() < 4e-7


def test_curves_leave_their_input_alone_and_round_trip():
    values = torch.rand(3, 64, 64, generator=torch.Generator().manual_seed(0))
    before = values.clone()
    back = srgb_to_linear(linear_to_srgb(values))
    assert torch.equal(values, before)
    assert torch.allclose(back, values, atol=1e-6)


def test_curves_pass_gradients():
    values = torch.linspace(0.001, 0.999, 101, dtype=torch.float64, requires_grad=True)
    encoded = linear_to_srgb(values)
    assert torch.allclose(encoded.detach(), torch.from_numpy(_iec_encode(values.detach().numpy())))
    encoded.sum().backward()
    slope = np.where(values.detach().numpy() <= 0.0031308, 12.92,
                     1.055 / 2.4 * values.detach().numpy() ** (1 / 2.4 - 1))
    assert np.allclose(values.grad.numpy(), slope)
    decoded = srgb_to_linear(values.detach().clone().requires_grad_())
    assert decoded.requires_grad


def test_raw_storage_adds_the_black_level_and_scales_the_light():
    light = torch.tensor([0.0, 0.5, 1.0, 2.0])
    stored = linear_to_raw(light, black_level=0.0625, gain=0.8)
    assert torch.allclose(stored, 0.0625 + 0.9375 * 0.8 * light.clamp(0, 1))


def test_the_combined_image_is_the_views_mean_in_the_light_named():
    """One definition (paper Eq. 7 at the views' brightness): the views' mean, in linear light
    by default (what the photodiodes gather), in the stored values when ``light="encoded"``;
    views stored linear (raw) average the same either way."""
    from dualpixel.errors import ParameterError
    from dualpixel.optics.tone import combined_image, combined_light

    dark, bright = np.zeros((2, 2, 3), np.float32), np.ones((2, 2, 3), np.float32)
    assert combined_light(dark, bright) == pytest.approx(0.5)
    # linear 0.5 in sRGB: 1.055 * 0.5 ** (1 / 2.4) - 0.055
    assert combined_image(dark, bright) == pytest.approx(0.735357, abs=1e-5)
    assert combined_image(dark, bright, light="encoded") == pytest.approx(0.5)
    grey = np.full((2, 2, 1), 0.2, np.float32)
    assert combined_image(grey, grey) == pytest.approx(0.2, abs=1e-6)  # equal views: themselves
    for light in ("linear", "encoded"):
        assert combined_image(dark, bright, encoding="linear", light=light) == pytest.approx(0.5)
    with pytest.raises(ParameterError, match="encoding must be one of"):
        combined_light(dark, bright, "gamma")
    with pytest.raises(ParameterError, match="light"):
        combined_image(dark, bright, light="stored")


def test_a_frames_combined_image_is_made_once_in_each_light():
    """``CombinedImage``: the same numbers as the functions, each light made on first read and
    kept; one view alone is its own image."""
    from dualpixel.optics.tone import CombinedImage, combined_image, combined_light

    rng = np.random.default_rng(3)
    left, right = rng.random((2, 12, 16, 3), dtype=np.float32)
    combined = CombinedImage(left, right)
    np.testing.assert_array_equal(combined.light, combined_light(left, right))
    np.testing.assert_array_equal(combined.encoded, combined_image(left, right))
    assert combined.light is combined.light and combined.encoded is combined.encoded
    alone = CombinedImage(left)
    np.testing.assert_array_equal(alone.encoded, left)
    np.testing.assert_allclose(alone.light, _iec_decode(left), atol=1e-6)
