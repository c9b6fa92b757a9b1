"""The overshoot limit: rims beyond the input's local range are cut, a steeper edge within it is
kept, grey views keep their shape, and the option reaches every way of deblurring."""

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

import dualpixel
from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.evaluation.target_free import check_deblurred
from dualpixel.inference import Deblurrer
from dualpixel.inference.brightness import tie_brightness
from dualpixel.inference.overshoot import combined_view, limit_overshoot, overshoot_radius
from dualpixel.io.images import read_rgb, write_png
from dualpixel.models import save_model
from dualpixel.optics import tone
from dualpixel.optics.tone import srgb_to_linear_array


@pytest.fixture(scope="module")
def edge():
    """A vertical step edge (0.2 | 0.7) blurred by a box of 9 px, as a DP pair with equal views;
    the sharp step; and a "deblurred" output that over-sharpens it: the step plus a rim of 0.15
    on both sides."""
    sharp = np.full((96, 256, 3), 0.2, np.float32)
    sharp[:, 128:] = 0.7
    blurred = cv2.blur(sharp, (9, 1), borderType=cv2.BORDER_REFLECT)
    rim = sharp.copy()
    rim[:, 122:128] -= 0.15
    rim[:, 128:134] += 0.15
    return blurred, sharp, np.clip(rim, 0, 1)


def test_a_rim_beyond_the_local_range_is_cut_and_a_steeper_edge_kept(edge):
    blurred, sharp, rim = edge
    limited = limit_overshoot(rim, blurred, blurred, radius=8, margin=2.0)
    # the rim is gone: nothing beyond the range of the blurred edge's two sides (plus 2 levels)
    assert limited.min() >= 0.2 - 2 / 255 - 1e-6 and limited.max() <= 0.7 + 2 / 255 + 1e-6
    assert np.abs(limited - sharp).max() <= 2 / 255 + 1e-5
    # the sharp step lies within that range: the limit leaves it as it is
    np.testing.assert_array_equal(limit_overshoot(sharp, blurred, blurred, radius=8), sharp)
    # and the target-free check sees the halo go
    before = check_deblurred(blurred, blurred, rim, noise_sigma=0)
    after = check_deblurred(blurred, blurred, limited, noise_sigma=0)
    assert before.overshoot > 10 and after.overshoot < 1


def test_the_range_is_the_views_mean_in_linear_light_and_grey_stays_grey(edge):
    blurred, _, rim = edge
    left, right = np.clip(blurred * 1.2, 0, 1), blurred * 0.8
    combined = combined_view(left, right)
    linear = srgb_to_linear_array
    np.testing.assert_allclose(linear(combined), 0.5 * (linear(left) + linear(right)), atol=1e-5)
    grey = limit_overshoot(rim[..., :1], blurred[..., :1], blurred[..., :1], radius=8)
    assert grey.shape == (96, 256, 1)
    np.testing.assert_allclose(grey[..., 0], limit_overshoot(rim, blurred, blurred,
                                                             radius=8)[..., 0])
    # the default window grows with the frame: 13 px at 840 px wide
    assert overshoot_radius(840) == 13 and overshoot_radius(1620) == 25


def test_bad_settings_are_refused(edge, refined_model):
    blurred, _, rim = edge
    with pytest.raises(ParameterError, match="radius"):
        limit_overshoot(rim, blurred, blurred, radius=-1)
    with pytest.raises(ParameterError, match="margin"):
        limit_overshoot(rim, blurred, blurred, margin=float("nan"))
    with pytest.raises(ParameterError, match="overshoot"):
        Deblurrer(refined_model, overshoot="none")


def test_the_option_reaches_the_deblurrer_the_api_and_the_commands(edge, refined_model,
                                                                    tmp_path, monkeypatch):
    blurred, _, _ = edge
    left, right = blurred, np.roll(blurred, 1, axis=1)
    plain = Deblurrer(refined_model, precision="fp32")(left, right)
    limited = Deblurrer(refined_model, precision="fp32", overshoot="limited")(left, right)
    np.testing.assert_allclose(limited, limit_overshoot(plain, left, right), atol=1e-6)
    both = Deblurrer(refined_model, precision="fp32", overshoot="limited",
                     brightness="tied")(left, right)
    np.testing.assert_allclose(both, tie_brightness(limited, left, right), atol=1e-6)
    # one combined image per frame: the views are linearised once for both output modes
    calls = []
    original = tone.combined_light
    monkeypatch.setattr(tone, "combined_light", lambda *a, **k: calls.append(1) or original(*a,
                                                                                             **k))
    again = Deblurrer(refined_model, precision="fp32", overshoot="limited",
                      brightness="tied")(left, right)
    assert len(calls) == 1
    np.testing.assert_array_equal(again, both)
    monkeypatch.undo()
    api = dualpixel.deblur(left, right, model=refined_model, device="cpu", precision="fp32",
                           overshoot="limited")
    np.testing.assert_allclose(api, limited, atol=1e-6)

    checkpoint = tmp_path / "model.safetensors"
    save_model(checkpoint, refined_model)
    write_png(tmp_path / "left.png", left)
    write_png(tmp_path / "right.png", right)
    out = tmp_path / "out.png"
    result = CliRunner().invoke(cli, ["deblur", "--left", str(tmp_path / "left.png"), "--right",
                                  str(tmp_path / "right.png"), "--checkpoint", str(checkpoint),
                                  "--precision", "fp32", "--overshoot", "limited", "-o",
                                  str(out)])
    assert result.exit_code == 0, result.output
    stored = [read_rgb(tmp_path / name) for name in ("left.png", "right.png")]
    reference = limit_overshoot(Deblurrer(refined_model, precision="fp32")(*stored), *stored)
    written = read_rgb(out)
    assert np.abs(written - reference).max() <= 1.5 / 255


def test_the_output_modes_on_the_networks_device_match_the_cpus(edge, refined_model):
    """``finish`` of a tensor (what a GPU hands over) runs the limit and the tie in torch
    (inference.device_finish): the same frame as the NumPy/OpenCV steps, for two views, one
    view and raw views whose light is known."""
    from dualpixel.optics.tone import CombinedImage, srgb_to_linear_array

    blurred, _, _ = edge
    rng = np.random.default_rng(2)
    left = np.clip(blurred + rng.normal(0, 0.02, blurred.shape), 0, 1).astype(np.float32)
    right = np.roll(left, 2, axis=1)
    deblurrer = Deblurrer(refined_model, precision="fp32", overshoot="limited",
                          brightness="tied")
    out = deblurrer.network_output(left, right)
    for views in ((left, right), (left, None)):  # (a one-view model's combined image: the view)
        as_tensor = torch.from_numpy(out).permute(2, 0, 1)
        np.testing.assert_allclose(deblurrer.finish(as_tensor, *views),
                                   deblurrer.finish(out, *views), atol=2e-5)
    light = 0.5 * (srgb_to_linear_array(left) + srgb_to_linear_array(right))
    known = CombinedImage.of_light(left, right, light)
    np.testing.assert_allclose(
        deblurrer.finish(torch.from_numpy(out).permute(2, 0, 1), left, right, combined=known),
        deblurrer.finish(out, left, right, combined=known), atol=2e-5)
    with pytest.raises(ParameterError, match=r"must be \(3, H, W\)"):
        deblurrer.finish(torch.from_numpy(out), left, right)  # (H, W, 3): not a network's
    deblurrer.reset()
    on_cpu = deblurrer(left, right)
    deblurrer._finish_on_device = True  # what a GPU's deblurrer does, here on the CPU
    deblurrer.reset()
    np.testing.assert_allclose(deblurrer(left, right), on_cpu, atol=2e-5)
