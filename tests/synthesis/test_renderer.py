import cv2
import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.psf import PSFParams
from dualpixel.optics.thin_lens import PAPER_LENS_SETS
from dualpixel.optics.tone import linear_to_srgb, srgb_to_linear
from dualpixel.synthesis.convolution import convolve_same
from dualpixel.synthesis.frame import draw_sequence, synthesize_frame
from dualpixel.synthesis.renderer import quantise_layers, render_dp_views

H, W = 96, 128


def textured(seed=0):
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 1, (H // 4, W // 4, 3)).astype(np.float32)
    smooth = cv2.resize(noise, (W, H), interpolation=cv2.INTER_CUBIC)
    return torch.from_numpy(smooth).permute(2, 0, 1)


def test_uniform_scene_renders_uniform_for_any_depth():
    rng = np.random.default_rng(1)
    blocks = rng.uniform(-25, 25, (6, 8)).astype(np.float32)
    coc = torch.from_numpy(cv2.resize(blocks, (W, H), interpolation=cv2.INTER_NEAREST))
    coc += torch.linspace(-3, 3, W)[None]  # plus a ramp: many layers, sharp and soft edges
    colour = torch.tensor([0.2, 0.5, 0.9])[:, None, None].expand(3, H, W).contiguous()
    for model in ("ours", "punnappurath", "disk", "gaussian"):
        left, right = render_dp_views(colour, coc, model=model)
        assert float((left - colour).abs().max()) < 1e-5, model
        assert float((right - colour).abs().max()) < 1e-5, model


def test_in_focus_plane_gives_identical_views_and_target():
    camera = PAPER_LENS_SETS["set1"]
    depth = np.full((H, W), camera.focus_distance, np.float32)
    rgb = textured().permute(1, 2, 0).numpy()
    for distortion in (False, True):
        draw = draw_sequence(0, "set1", noise=False, distortion=distortion)
        frame = synthesize_frame(rgb, depth, draw)
        assert torch.equal(frame.left, frame.right)
        assert float((frame.left - frame.target).abs().max()) < 1e-6
        assert float(frame.defocus.abs().max()) == 0.0


@pytest.mark.parametrize("light", ["encoded", "linear"])
def test_the_in_focus_blur_softens_both_views_and_not_the_target(light):
    """``base_blur``: in focus, each view is the target blurred (in the light the lens blurs)
    by OpenCV's Gaussian of the drawn std; the target and the defocus map are untouched."""
    camera = PAPER_LENS_SETS["set1"]
    depth = np.full((H, W), camera.focus_distance, np.float32)
    rgb = textured().permute(1, 2, 0).numpy()
    draw = draw_sequence(0, "set1", noise=False, distortion=False, light=light,
                         base_blur=(0.7, 0.7))
    rgb = rgb.clip(0.0, 1.0)
    frame = synthesize_frame(rgb, depth, draw)
    scene = rgb if light == "encoded" else srgb_to_linear(torch.from_numpy(rgb)).numpy()
    blurred = cv2.GaussianBlur(scene, (0, 0), 0.7, borderType=cv2.BORDER_REFLECT)
    if light == "linear":
        blurred = linear_to_srgb(torch.from_numpy(blurred)).numpy()
    expected = torch.from_numpy(blurred).permute(2, 0, 1)
    for view in (frame.left, frame.right, frame.combined):
        torch.testing.assert_close(view, expected, rtol=0, atol=2e-6)
    assert float((frame.target - torch.from_numpy(rgb).permute(2, 0, 1)).abs().max()) < 1e-6
    sharp = synthesize_frame(rgb, depth, draw_sequence(0, "set1", noise=False, distortion=False,
                                                       light=light))
    assert float((sharp.left - frame.left).abs().max()) > 0.05  # it does blur
    # a window's margin grows by the Gaussian's reach: in focus, the PSF's own margin is small
    wide = draw_sequence(0, "set1", noise=False, distortion=False, light=light,
                         base_blur=(2.5, 2.5))
    whole = synthesize_frame(rgb, depth, wide)
    part = synthesize_frame(rgb, depth, wide, window=(40, 50, 24, 32))
    torch.testing.assert_close(part.left, whole.left[:, 40:64, 50:82], rtol=0, atol=1e-6)


def test_the_in_focus_blur_is_drawn_from_its_own_stream():
    """Drawn uniformly from the range per seed, recorded, and the other draws unchanged;
    refused outside [0, 3] px or as a reversed range."""
    draws = [draw_sequence(seed, "set2", base_blur=(0.2, 0.8)) for seed in range(20)]
    stds = [draw.base_blur for draw in draws]
    assert all(0.2 <= s <= 0.8 for s in stds) and len(set(stds)) == 20
    assert draw_sequence(5, "set2", base_blur=(0.2, 0.8)).base_blur == stds[5]
    assert draws[5].describe()["base_blur"] == stds[5]
    plain = draw_sequence(5, "set2")
    assert plain.base_blur == 0.0 and "base_blur" not in plain.describe()
    assert (plain.psf, plain.noise_sigma, plain.distortion) == (
        draws[5].psf, draws[5].noise_sigma, draws[5].distortion)
    for bad, message in (((-0.1, 0.5), "base_blur"), ((0.5, 4.0), "base_blur"),
                         ((0.8, 0.2), "LOW <= HIGH"), ((0.5,), "two stds")):
        with pytest.raises(ParameterError, match=message):
            draw_sequence(5, "set2", base_blur=bad)


def horizontal_shift(reference: torch.Tensor, moved: torch.Tensor) -> float:
    """Sub-pixel x displacement of ``moved`` relative to ``reference`` (phase correlation)."""
    a = reference.mean(0).double().numpy()
    b = moved.mean(0).double().numpy()
    window = cv2.createHanningWindow((W, H), cv2.CV_64F)
    (dx, _dy), _ = cv2.phaseCorrelate(a, b, window)
    return dx


@pytest.mark.parametrize("model", ["ours", "punnappurath"])
def test_views_shift_in_opposite_directions_growing_with_defocus(model):
    image = textured(2)
    shifts = {}
    for radius in (-12.0, -6.0, 6.0, 12.0):
        left, right = render_dp_views(image, torch.full((H, W), radius), model=model)
        shifts[radius] = (horizontal_shift(image, left), horizontal_shift(image, right))
    for radius, (left_dx, right_dx) in shifts.items():
        # behind focus (r > 0) the left view moves left and the right view right; in front, swapped
        assert np.sign(left_dx) == -np.sign(radius) and np.sign(right_dx) == np.sign(radius)
        assert left_dx == pytest.approx(-right_dx, abs=0.3)
    assert abs(shifts[12.0][1]) > abs(shifts[6.0][1]) > 0.5
    assert abs(shifts[-12.0][1]) > abs(shifts[-6.0][1]) > 0.5


def two_planes(fg_radius: float, bg_radius: float):
    background, foreground = torch.tensor([0.1, 0.2, 0.8]), torch.tensor([0.9, 0.6, 0.1])
    inside = torch.zeros(H, W, dtype=torch.bool)
    inside[30:66, 40:88] = True
    image = torch.where(inside, foreground[:, None, None], background[:, None, None])
    coc = torch.where(inside, torch.tensor(fg_radius), torch.tensor(bg_radius))
    return image, coc, inside, background, foreground


def test_blurred_foreground_spreads_over_sharp_background():
    image, coc, _inside, background, foreground = two_planes(-8.0, 0.0)
    left, right = render_dp_views(image, coc, PSFParams(alpha=1.0))
    for view in (left, right):
        ring = view[:, 30:66, 30:38]  # background pixels within the blur radius of the edge
        assert float((ring - background[:, None, None]).abs().amax()) > 0.1
        far = view[:, 5:15, 5:25]
        torch.testing.assert_close(far, background[:, None, None].expand_as(far))
    # the foreground's own interior stays its colour
    centre = left[:, 45:51, 60:68]
    torch.testing.assert_close(centre, foreground[:, None, None].expand_as(centre), atol=1e-5,
                               rtol=0)


def test_blurred_background_does_not_bleed_over_sharp_foreground():
    image, coc, inside, background, foreground = two_planes(0.0, 10.0)
    left, right = render_dp_views(image, coc)
    for view in (left, right):
        # the sharp foreground is untouched, right up to its edge
        fg = view[:, inside]
        torch.testing.assert_close(fg, foreground[:, None].expand_as(fg), atol=1e-5, rtol=0)
        # and no foreground colour leaks into the blurred background next to it
        bg = view[:, ~inside]
        torch.testing.assert_close(bg, background[:, None].expand_as(bg), atol=1e-5, rtol=0)


def test_naive_hard_mask_rendering_differs_at_occlusions():
    """The authors' approach (blur the whole image per layer, then hard-mask) cannot spread a
    blurred foreground over the background; ours does."""
    image, coc, inside, background, _ = two_planes(-8.0, 0.0)
    ours, _ = render_dp_views(image, coc)
    kernels = torch.stack(list(__import__("dualpixel").optics.dp_psf(-8.0))) * 2
    naive = torch.where(inside, convolve_same(image, kernels)[0], image)
    ring = (slice(None), slice(30, 66), slice(32, 38))
    assert float((naive[ring] - background[:, None, None]).abs().max()) < 1e-6
    assert float((ours[ring] - background[:, None, None]).abs().max()) > 0.1


def test_layers_are_bounded_and_keep_exact_values():
    coc = torch.linspace(-40, 40, 2000).reshape(40, 50)
    labels, layer_coc = quantise_layers(coc, 500)
    assert layer_coc.numel() <= 500 and int(labels.max()) == layer_coc.numel() - 1
    _flat, values = quantise_layers(torch.full((4, 4), 2.5), 500)
    assert values.tolist() == [2.5]


def test_direct_and_fft_convolution_agree():
    planes, kernels = torch.rand(4, 37, 45, dtype=torch.float64), torch.rand(2, 11, 11,
                                                                            dtype=torch.float64)
    torch.testing.assert_close(convolve_same(planes, kernels, method="direct"),
                               convolve_same(planes, kernels, method="fft"))


def _psnr8(a: torch.Tensor, b: torch.Tensor) -> float:
    a8, b8 = (torch.round(x.clamp(0, 1) * 255) for x in (a, b))
    mse = float(((a8 - b8) ** 2).mean())
    return float("inf") if mse == 0 else 10 * np.log10(255**2 / mse)


@pytest.mark.parametrize(("camera", "large_blur"), [("set0", False), ("set2", True),
                                                    ("set4", True)])
def test_default_rendering_stays_within_45_db_of_exact(camera, large_blur):
    from dualpixel.optics.thin_lens import PAPER_LENS_SETS, coc_radius
    from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence

    rgb, depth = render_scene_sequence(3, SceneConfig(width=192, height=128, frames=1,
                                                      leaves=12))[0]
    image = torch.from_numpy(rgb).permute(2, 0, 1)
    coc = coc_radius(torch.from_numpy(depth), PAPER_LENS_SETS[camera])
    # large blur: layers at reduced resolution are used
    assert (float(coc.abs().max()) > 10) == large_blur
    exact = render_dp_views(image, coc, mode="exact")
    default = render_dp_views(image, coc)
    for a, b in zip((*exact, (exact[0] + exact[1]) / 2), (*default, (default[0] + default[1]) / 2)):
        assert _psnr8(a, b) >= 45


def test_fast_bands_give_the_same_image_as_whole_layers(monkeypatch):
    """Convolving a layer band by band is exact, whatever the band height."""
    from dualpixel.synthesis import fast_renderer

    torch.manual_seed(0)
    image = torch.rand(3, 70, 90)
    coc = torch.linspace(-4.0, 4.0, 90).expand(70, 90) + 0.5 * torch.rand(70, 90)
    monkeypatch.setattr(fast_renderer, "STRIP_MIN_KERNEL", 1)  # every layer through the bands
    monkeypatch.setattr(fast_renderer, "STRIP_ROWS", 1000)
    whole = fast_renderer.render_fast(image, coc)
    monkeypatch.setattr(fast_renderer, "STRIP_ROWS", 8)
    banded = fast_renderer.render_fast(image, coc)
    for a, b in zip(whole, banded):
        torch.testing.assert_close(a, b, atol=1e-5, rtol=0)


def test_unblurred_layers_pasted_at_once_equal_compositing_each():
    """Near-focus layers with [[1]] kernels are copied in one go: the same bytes as compositing
    them one by one over whatever lies below."""
    from dualpixel.synthesis import fast_renderer
    from dualpixel.synthesis.layers import row_extents

    torch.manual_seed(0)
    opaque = torch.cat((torch.rand(40, 50, 3), torch.ones(40, 50, 1)), dim=-1)
    labels = torch.randint(0, 6, (40, 50))
    below = torch.rand(2, 40, 50, 4)
    first, last = fast_renderer._strip_extents(row_extents(labels, 6), 50)
    one_by_one, pasted = below.clone(), below.clone()
    for j in (4, 3, 2):  # far to near
        fast_renderer._composite_strips(one_by_one, opaque, labels, j, first[j], last[j],
                                        torch.ones(2, 1, 1))
    fast_renderer._paste_unblurred(pasted, opaque, labels, [4, 3, 2])
    assert torch.equal(one_by_one, pasted)
    assert torch.equal(pasted[:, labels == 1], below[:, labels == 1])
    assert torch.equal(pasted[:, labels == 3], opaque[labels == 3].expand(2, -1, -1))


def test_row_extents_and_bounding_boxes_match_a_direct_search():
    from dualpixel.synthesis.layers import bounding_boxes, row_extents

    labels = torch.randint(0, 4, (23, 31), generator=torch.Generator().manual_seed(3))
    labels[:, :5] = labels[:, :5].clamp(max=2)  # label 3 never in the first columns
    first, last = row_extents(labels, 5)  # label 4 never occurs
    boxes = bounding_boxes(labels, 5).tolist()
    for j in range(5):
        rows, cols = np.nonzero(labels.numpy() == j)
        for row in range(23):
            in_row = cols[rows == row]
            expected = (int(in_row.min()), int(in_row.max())) if in_row.size else (31, -1)
            assert (int(first[j, row]), int(last[j, row])) == expected
        expected = ([int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())]
                    if rows.size else [23, -1, 31, -1])
        assert boxes[j] == expected


def test_fast_layers_are_unions_of_exact_layers():
    coc = torch.linspace(-40.0, 40.0, 20000).reshape(100, 200)
    exact, _ = quantise_layers(coc, 500, mode="exact")
    fast, values = quantise_layers(coc, 500, mode="fast")
    assert values.numel() < 500
    # every exact layer lies inside one fast layer, and near focus they coincide
    pairs = torch.unique(exact * 1000 + fast)
    assert pairs.numel() == int(exact.max()) + 1
    near = coc.abs() < 2
    assert torch.unique(exact[near]).numel() == torch.unique(fast[near]).numel()


def test_reduced_layers_composited_by_covered_regions_equal_the_whole_group(monkeypatch):
    """Upsampling only the covered blocks of a reduced-resolution group changes no pixel."""
    from dualpixel.optics.thin_lens import PAPER_LENS_SETS, coc_radius
    from dualpixel.synthesis import fast_renderer
    from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence

    rgb, depth = render_scene_sequence(5, SceneConfig(width=256, height=160, frames=1,
                                                      leaves=16))[0]
    image = torch.from_numpy(rgb).permute(2, 0, 1)
    coc = coc_radius(torch.from_numpy(depth), PAPER_LENS_SETS["set4"])
    regions = fast_renderer._covered_regions(torch.ones(2, 9, 7, 1))
    assert regions == [(0, 9, 0, 7)]
    split = fast_renderer.render_fast(image, coc)
    monkeypatch.setattr(fast_renderer, "_covered_regions",
                        lambda alpha, gap=8: [(0, alpha.shape[1], 0, alpha.shape[2])])
    whole = fast_renderer.render_fast(image, coc)
    for a, b in zip(split, whole):
        torch.testing.assert_close(a, b, atol=1e-6, rtol=0)


def test_linear_light_blur_conserves_light_not_stored_values():
    """A lens mixes light: blurred in linear light (``light="linear"``) a frame keeps its mean
    linear intensity, blurred in the stored values (the paper's generator) its mean stored
    value; flat regions far from the edge are the same either way."""
    from dualpixel.optics.psf import PSFParams
    from dualpixel.optics.thin_lens import ThinLens
    from dualpixel.optics.tone import srgb_to_linear
    from dualpixel.synthesis.frame import SequenceDraw, synthesize_frame

    image = np.full((64, 96, 3), 0.05, np.float32)
    image[:, 40:56] = 0.9  # a bright bar on a dark ground
    depth = np.full((64, 96), 8.0, np.float32)
    lens = ThinLens(0.05, 2.0, 2.0, pixel_pitch=1.0)
    camera = ThinLens(0.05, 2.0, 2.0, pixel_pitch=lens.coc_scale / 8.0)
    frames = {light: synthesize_frame(image, depth, SequenceDraw(
        lens=camera, psf=PSFParams(), distortion=None, noise_sigma=None, light=light))
        for light in ("encoded", "linear")}
    inner = (slice(None), slice(None), slice(16, 80))  # away from the frame's borders
    source = torch.from_numpy(image).permute(2, 0, 1)[inner]
    encoded, linear = (frames[k].combined[inner] for k in ("encoded", "linear"))
    assert float(encoded.mean()) == pytest.approx(float(source.mean()), rel=1e-3)
    assert float(srgb_to_linear(linear).mean()) == pytest.approx(
        float(srgb_to_linear(source).mean()), rel=1e-3)
    # the bright bar spreads further into the dark ground in linear light
    assert float(linear[:, :, 19].mean()) > float(encoded[:, :, 19].mean()) + 0.02
    torch.testing.assert_close(frames["linear"].target, frames["encoded"].target, atol=1e-5,
                               rtol=0)
    torch.testing.assert_close(linear[:, :, :4], encoded[:, :, :4], atol=1e-4, rtol=0)


def test_raw_storage_keeps_the_light_in_the_stored_values():
    """Views stored as raw values (``raw=(black_level, gain)``, a phone's DP data) are linear in
    light: blurred, the combined image keeps the sharp target's mean stored value, every value
    lies between the black level and black + (1 - black) * gain, and the target is the sRGB
    frame's light stored so."""
    from dualpixel.optics.psf import PSFParams
    from dualpixel.optics.thin_lens import ThinLens
    from dualpixel.optics.tone import srgb_to_linear
    from dualpixel.synthesis.frame import SequenceDraw, synthesize_frame

    image = np.full((64, 96, 3), 0.05, np.float32)
    image[:, 40:56] = 0.9
    depth = np.full((64, 96), 8.0, np.float32)
    lens = ThinLens(0.05, 2.0, 2.0, pixel_pitch=1.0)
    camera = ThinLens(0.05, 2.0, 2.0, pixel_pitch=lens.coc_scale / 8.0)
    black, gain = 0.0625, 0.5
    frame = synthesize_frame(image, depth, SequenceDraw(
        lens=camera, psf=PSFParams(), distortion=None, noise_sigma=None, light="linear",
        raw=(black, gain)))
    inner = (slice(None), slice(None), slice(16, 80))
    light = srgb_to_linear(torch.from_numpy(image).permute(2, 0, 1))
    torch.testing.assert_close(frame.target, black + (1 - black) * gain * light, atol=1e-6,
                               rtol=0)
    assert float(frame.combined[inner].mean()) == pytest.approx(
        float(frame.target[inner].mean()), rel=1e-3)
    for view in (frame.left, frame.right, frame.combined):
        assert float(view.min()) >= black - 1e-6
        assert float(view.max()) <= black + (1 - black) * gain + 1e-6
    torch.testing.assert_close(frame.combined, (frame.left + frame.right) / 2)
    with pytest.raises(ParameterError, match="raw storage needs light 'linear'"):
        SequenceDraw(lens=camera, psf=PSFParams(), distortion=None, noise_sigma=None,
                     raw=(black, gain))
    with pytest.raises(ParameterError, match=r"black_level \(of full scale\) must be in"):
        SequenceDraw(lens=camera, psf=PSFParams(), distortion=None, noise_sigma=None,
                     light="linear", raw=(0.7, gain))


def test_a_raw_sequence_draws_its_exposure_gain_from_its_seed():
    from dualpixel.synthesis.frame import draw_sequence

    gains = [draw_sequence(seed, "set1", light="linear", raw_black_level=0.0625,
                           raw_gains=(0.4, 1.0)).raw[1] for seed in range(40)]
    assert all(0.4 <= g <= 1.0 for g in gains) and max(gains) - min(gains) > 0.3
    again = draw_sequence(7, "set1", light="linear", raw_black_level=0.0625,
                          raw_gains=(0.4, 1.0))
    assert again.raw == (0.0625, gains[7])
    assert again.describe()["raw"] == {"black_level": 0.0625, "gain": gains[7]}
    plain = draw_sequence(7, "set1", light="linear")
    assert plain.raw is None and "raw" not in plain.describe()
    assert plain.psf == again.psf and plain.noise_sigma == again.noise_sigma  # same draws


def test_the_old_names_of_a_sequence_draw_still_import_with_a_warning():
    import dualpixel.synthesis as synthesis

    with pytest.warns(FutureWarning, match="draw_recipe is now draw_sequence"):
        assert synthesis.draw_recipe is synthesis.draw_sequence
    with pytest.warns(FutureWarning, match="SequenceRecipe is now SequenceDraw"):
        assert synthesis.SequenceRecipe is synthesis.SequenceDraw
    with pytest.raises(AttributeError):
        synthesis.no_such_name  # noqa: B018


@pytest.mark.parametrize(("camera", "settings", "atol"), [
    ("set0", {}, 1e-4),  # distortion, noise: positions mapped in float64 against float32
    ("set4", {}, 1e-4),  # large blur: layers at 1/2 .. 1/8 resolution
    ("set2", {"light": "linear", "disparity_ratio": (0.7, 0.9, 0.95)}, 1e-4),
    ("set2", {"disparity_ratio": (0.7, 0.9, 0.95), "disparity_falloff": 0.4,
              "distortion": False}, 1e-6),
    ("set1", {"light": "linear", "raw_black_level": 0.0625, "distortion": False}, 1e-6),
    ("set3", {"distortion": False}, 1e-6),
    # the in-focus blur reads past the PSF's margin: the window's margin grows by its reach
    ("set3", {"distortion": False, "base_blur": (1.5, 1.5)}, 1e-6),
    ("set0", {"light": "linear", "base_blur": (0.4, 0.9)}, 1e-4),
    # blur of 40 px, layers at 1/8: a margin without the reduced resolutions' reach is 7e-6 off
    ("set4", {"distortion": False, "noise": False, "size": (384, 256)}, 1e-6),
])
def test_a_window_renders_as_that_region_of_the_whole_frame(camera, settings, atol):
    """A window (a training crop on the fly) rendered alone, with the frame's layers and its
    blur margin, equals the same region of the whole frame's render: views, combined image,
    target, defocus and noise, at the frame's corners, inside it and off the reduced grid."""
    from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence

    settings = dict(settings)
    width, height = settings.pop("size", (256, 176))
    rgb, depth = render_scene_sequence(3, SceneConfig(width=width, height=height, frames=1,
                                                      leaves=12))[0]
    draw = draw_sequence(7, camera, **settings)
    whole = synthesize_frame(rgb, depth, draw, noise_seed=3)
    for top, left, rows, cols in ((0, 0, 64, 64), (height - 64, width - 80, 64, 80),
                                  (37, 101, 48, 64), (100, 150, 40, 40)):
        part = synthesize_frame(rgb, depth, draw, noise_seed=3,
                                window=(top, left, rows, cols))
        for name in ("left", "right", "combined", "target", "defocus"):
            expected = getattr(whole, name)[..., top : top + rows, left : left + cols]
            torch.testing.assert_close(getattr(part, name), expected, rtol=0,
                                       atol=atol if name != "defocus" else 2e-3,
                                       msg=lambda m, n=name: f"{camera} {n}: {m}")


def test_windows_outside_the_frame_or_in_exact_mode_are_refused():
    image = np.zeros((32, 48, 3), np.float32)
    depth = np.full((32, 48), 3.0, np.float32)
    draw = draw_sequence(1, "set0")
    with pytest.raises(ParameterError, match="does not lie inside the 48x32 frame"):
        synthesize_frame(image, depth, draw, window=(0, 40, 16, 16))
    exact = draw_sequence(1, "set0", render_mode="exact")
    with pytest.raises(ParameterError, match="fast"):
        synthesize_frame(image, depth, exact, window=(0, 0, 16, 16))
