"""The batched renderer: the default renderer's layers and compositing, many frames at once."""

from __future__ import annotations

import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.psf import PSFParams
from dualpixel.optics.thin_lens import PAPER_LENS_SETS, coc_radius
from dualpixel.synthesis.batched_renderer import crop_margin, render_batch
from dualpixel.synthesis.frame import (
    common_regions,
    draw_sequence,
    synthesize_frame,
    synthesize_frames,
)
from dualpixel.synthesis.layers import quantise_layers
from dualpixel.synthesis.renderer import render_dp_views
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence


def _psnr(a: torch.Tensor, b: torch.Tensor) -> float:
    return float(10 * torch.log10(1 / ((a - b) ** 2).mean().clamp_min(1e-20)))


@pytest.fixture(scope="module")
def frames():
    """Three 320x224 dead-leaves frames with their depth (m)."""
    config = SceneConfig(width=320, height=224, frames=1, leaves=20)
    out = [render_scene_sequence(seed, config)[0] for seed in range(3)]
    images = torch.stack([torch.from_numpy(rgb).permute(2, 0, 1) for rgb, _ in out])
    depths = torch.stack([torch.from_numpy(depth) for _, depth in out])
    return images, depths


@pytest.mark.parametrize("name", ["set0", "set1", "set2", "set3", "set4"])
def test_batch_is_the_default_renderer_and_near_exact(frames, name):
    images, depths = frames
    coc = coc_radius(depths, PAPER_LENS_SETS[name])
    left, right = render_batch(images[:2], coc[:2])
    assert left.shape == right.shape == images[:2].shape
    for b in range(2):
        fast = render_dp_views(images[b], coc[b])
        exact = render_dp_views(images[b], coc[b], mode="exact")
        assert _psnr(left[b], fast[0]) > 90 and _psnr(right[b], fast[1]) > 90
        for mine, default, reference in (
                (left[b], fast[0], exact[0]), (right[b], fast[1], exact[1]),
                ((left[b] + right[b]) / 2, (fast[0] + fast[1]) / 2, (exact[0] + exact[1]) / 2)):
            assert _psnr(mine, reference) >= max(45.0, _psnr(default, reference) - 0.05), name


@pytest.mark.parametrize("factor", [0, 16])
def test_tiles_and_boxes_render_alike(frames, monkeypatch, factor):
    """Every resolution rendered in boxes (no tiles), or in tiles (up to 1/16), gives the
    default renderer's views: the two ways differ in what they convolve, not in the result."""
    import dualpixel.synthesis.batched_renderer as batched

    monkeypatch.setattr(batched, "TILED_MAX_FACTOR", factor)
    images, depths = frames
    coc = coc_radius(depths[:1], PAPER_LENS_SETS["set4"])  # layers from 1/1 to 1/8
    left, right = render_batch(images[:1], coc)
    fast = render_dp_views(images[0], coc[0])
    assert _psnr(left[0], fast[0]) > 90 and _psnr(right[0], fast[1]) > 90


def test_each_frame_keeps_its_own_psf_and_model(frames):
    images, depths = frames
    coc = coc_radius(depths, PAPER_LENS_SETS["set2"])
    params = [PSFParams(), PSFParams(n=6.0, alpha=0.3), None]
    models = ["ours", "ours", "gaussian"]
    left, right = render_batch(images, coc, params, model=models)
    for b in range(3):
        alone = render_dp_views(images[b], coc[b], params[b], model=models[b])
        assert _psnr(left[b], alone[0]) > 90 and _psnr(right[b], alone[1]) > 90
    # the frames differ by their PSFs: the gaussian frame is not the "ours" render
    ours = render_dp_views(images[2], coc[2])
    assert _psnr(left[2], ours[0]) < 60


def test_a_crop_with_its_margin_is_that_region_of_the_whole_frame(frames):
    images, depths = frames
    coc = coc_radius(depths[0], PAPER_LENS_SETS["set1"])  # up to ~20 px of blur
    whole_left, whole_right = render_batch(images[:1], coc[None])
    labels, layer_coc = quantise_layers(coc, 500, mode="fast")
    margin = crop_margin(float(coc.abs().max()))
    y0, x0, size = 16, 96, 48  # the crop's context clipped at the top, whole at the sides
    top, left_edge = (max(v - margin, 0) // 16 * 16 for v in (y0, x0))  # on the 16-px grid
    bottom, right_edge = min(y0 + size + margin, 224), min(x0 + size + margin, 320)
    region = (slice(top, bottom), slice(left_edge, right_edge))
    crop_left, crop_right = render_batch(
        images[:1, :, region[0], region[1]], coc[None, region[0], region[1]],
        layers=[(labels[region], layer_coc)])
    inner = (slice(y0 - top, y0 - top + size), slice(x0 - left_edge, x0 - left_edge + size))
    for crop, whole in ((crop_left, whole_left), (crop_right, whole_right)):
        torch.testing.assert_close(crop[0][:, inner[0], inner[1]],
                                   whole[0][:, y0:y0 + size, x0:x0 + size], atol=2e-5, rtol=0)


def test_regions_grow_to_one_size_on_the_grid_inside_the_frame():
    """Regions of a batch of windows share one size, each holds its own, starts on the 16-px
    grid and stays in the frame, also where a region reaches the frame's far edge."""
    regions = [(0, 70, 32, 90), (150, 224, 280, 320), (37 // 8 * 8, 120, 0, 47),
               (200, 224, 300, 320)]
    grown = common_regions(regions, (224, 320))
    sizes = {(r1 - r0, c1 - c0) for r0, r1, c0, c1 in grown}
    assert len(sizes) == 1
    for (r0, r1, c0, c1), (g0, g1, g2, g3) in zip(regions, grown):
        assert g0 <= r0 and g1 >= r1 and g2 <= c0 and g3 >= c1
        assert g0 % 16 == 0 and g2 % 16 == 0 and g1 <= 224 and g3 <= 320
    assert common_regions([(5, 219, 3, 40)], (224, 320)) == [(0, 224, 0, 53)]


def test_windows_of_many_frames_render_as_those_regions_of_their_frames():
    """synthesize_frames with windows (training crops rendered together, each frame its own
    camera, blur margin, distortion and noise) gives each window of that frame's whole render."""
    config = SceneConfig(width=256, height=176, frames=1, leaves=12)
    scenes = [render_scene_sequence(seed, config)[0] for seed in (3, 4, 5)]
    draws = [draw_sequence(7, "set0"), draw_sequence(8, "set4", distortion=False),
             draw_sequence(9, "set2", light="linear")]
    windows = [(0, 0, 64, 64), (176 - 64, 256 - 80, 64, 80), (37, 101, 48, 64)]
    together = synthesize_frames(scenes, draws, [3, 4, 5], windows=windows)
    for k, ((rgb, depth), draw, seed, (top, left, rows, cols), part) in enumerate(zip(
            scenes, draws, (3, 4, 5), windows, together)):
        whole = synthesize_frame(rgb, depth, draw, noise_seed=seed)
        for name in ("left", "right", "combined", "target", "defocus"):
            expected = getattr(whole, name)[..., top : top + rows, left : left + cols]
            torch.testing.assert_close(getattr(part, name), expected, rtol=0,
                                       atol=1e-4 if name != "defocus" else 2e-3,
                                       msg=lambda m, n=name, k=k: f"frame {k} {n}: {m}")


def test_bad_windows_are_refused():
    rgb, depth = render_scene_sequence(3, SceneConfig(width=64, height=48, frames=1,
                                                      leaves=4))[0]
    draw = draw_sequence(7, "set0")
    with pytest.raises(ParameterError, match="one entry per frame"):
        synthesize_frames([(rgb, depth)], [draw], [0], windows=[None, None])
    with pytest.raises(ParameterError, match="does not lie inside the 64x48 frame"):
        synthesize_frames([(rgb, depth)], [draw], [0], windows=[(40, 0, 16, 16)])


def test_deterministic_and_in_double_precision(frames):
    images, depths = frames[0][:1], frames[1][:1]
    coc = coc_radius(depths, PAPER_LENS_SETS["set1"])
    first = render_batch(images, coc)
    again = render_batch(images, coc)
    assert all(torch.equal(a, b) for a, b in zip(first, again))
    double = render_batch(images.double(), coc.double())
    assert double[0].dtype == torch.float64
    assert _psnr(double[0].float(), first[0]) > 90


def test_bad_batches_are_refused(frames):
    images, depths = frames
    coc = coc_radius(depths, PAPER_LENS_SETS["set0"])
    with pytest.raises(ParameterError, match=r"\(B, C, H, W\)"):
        render_batch(images[0], coc[0])
    with pytest.raises(ParameterError, match="one entry per frame"):
        render_batch(images, coc, [PSFParams()])
    with pytest.raises(ParameterError, match="floating point"):
        render_batch((images * 255).to(torch.uint8), coc)
