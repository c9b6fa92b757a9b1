import itertools

import cv2
import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.inference import Deblurrer, TileGrid, deblur_sequence
from dualpixel.inference.multiscale import fuse_scales, half_resolution
from dualpixel.io.images import read_rgb
from dualpixel.models import build_model

#: Exact comparisons run in float32 (the default picks bf16 on CPUs that have it).
FP32 = {"precision": "fp32"}


@pytest.fixture(scope="module")
def tiny_model():
    torch.manual_seed(0)
    return build_model("rdpd", width=0.125).eval()


@pytest.fixture(scope="module")
def canon_views(shared_dir):
    folder = shared_dir / "data" / "canon-dp-real" / "scene_02"
    return read_rgb(folder / "view0.png"), read_rgb(folder / "view1.png")


@pytest.fixture(scope="module")
def made_views():
    """400x600 views the project makes itself (procedural photo scene, linear-light blur), so
    tiling is checked without ../shared too (issue #76)."""
    import dualpixel
    from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence

    rgb, depth = render_scene_sequence(7, SceneConfig(width=600, height=400, frames=1,
                                                      layout="photo"))[0]
    frame = dualpixel.synthesize(rgb, depth, seed=7)
    return np.asarray(frame["left"], np.float32), np.asarray(frame["right"], np.float32)


@pytest.mark.parametrize("views", ["made_views", "canon_views"])
@pytest.mark.parametrize("name", ["tiny_model", "refined_model", "naf_model"])
def test_tiled_inference_matches_whole_image(name, views, request):
    tiny_model = request.getfixturevalue(name)
    left, right = (v[:400, :600] for v in request.getfixturevalue(views))
    whole = Deblurrer(tiny_model, precision="fp32")
    tiled = Deblurrer(tiny_model, precision="fp32", tile=384, overlap=192)
    for _ in range(2):  # second frame: per-tile recurrent states
        a, b = whole(left, right), tiled(left, right)
        assert np.abs(a - b).max() < 1e-3


def test_a_frame_too_large_for_memory_runs_in_tiles_with_a_warning(tiny_model, canon_views,
                                                                   monkeypatch):
    from dualpixel.inference import deblur as deblur_module

    left, right = canon_views
    explicit = Deblurrer(tiny_model, precision="fp32", tile=192)(left, right)
    per_pixel = deblur_module.pass_memory(tiny_model, 1)
    # room for batches of four 192-px tiles in half of it, not for the whole 840x512 frame
    room = 2 * deblur_module.pass_memory(tiny_model, 4 * 192**2)
    assert room < per_pixel * 840 * 512
    monkeypatch.setattr(deblur_module, "available_memory", lambda: room)
    deblurrer = Deblurrer(tiny_model, precision="fp32")
    with pytest.warns(UserWarning, match=r"840x512 frame needs about .* tiles of 192 px"):
        tiled = deblurrer(left, right)
    assert deblurrer.tile_for(512, 840) == 192  # and every later frame of the sequence
    np.testing.assert_array_equal(tiled, explicit)
    # not even the smallest faithful tile fits: refused, with the numbers, before any pass
    monkeypatch.setattr(deblur_module, "available_memory", lambda: 10 * per_pixel)
    with pytest.raises(ParameterError, match=r"840x512 frame needs about .* GiB .* 128-px"):
        Deblurrer(tiny_model, precision="fp32")(left, right)


def test_tile_grid_covers_and_validates():
    grid = TileGrid(128, 32)
    span, starts = grid.layout(400)
    assert span <= 128 and span % 16 == 0 and starts[0] == 0 and starts[-1] + span == 400
    assert all(s % 16 == 0 for s in starts)
    assert all(b - a <= span - 32 for a, b in itertools.pairwise(starts))
    # tiles of one size that just cover: at 1680x1120 and tile 512, 1.3x the pixels at most
    # (fixed 512-px tiles would be 12 x 512^2 = 1.67x)
    grid = TileGrid(512, 64)
    (h_span, tops), (w_span, lefts) = grid.layout(1120), grid.layout(1680)
    assert len(tops) * h_span * len(lefts) * w_span <= 1.3 * 1680 * 1120
    with pytest.raises(ValueError, match="multiple of 16"):
        TileGrid(100, 10)


def test_sequence_inference_equals_forward_with_state(tiny_model):
    rng = np.random.default_rng(1)
    frames = [{"left": rng.random((30, 44, 3), dtype=np.float32),
               "right": rng.random((30, 44, 3), dtype=np.float32)} for _ in range(3)]
    outputs = deblur_sequence(tiny_model, frames, precision="fp32")
    from dualpixel.inference.deblur import frame_tensor

    x = torch.stack([frame_tensor(tiny_model, f["left"], f["right"])[0] for f in frames])[None]
    with torch.no_grad():
        expected, _ = tiny_model(x)
    for t, output in enumerate(outputs):
        np.testing.assert_allclose(output, expected[0, t].permute(1, 2, 0).numpy(), atol=1e-6)
    # A fresh Deblurrer per frame (no carried state) gives something else for later frames.
    fresh = Deblurrer(tiny_model, precision="fp32")(frames[2]["left"], frames[2]["right"])
    assert not np.allclose(fresh, outputs[2], atol=1e-7)


def test_frame_trained_model_starts_every_frame_afresh(tiny_synthetic_dataset, tmp_path):
    from dualpixel.models import load_model, save_model
    from dualpixel.training import load_config, train

    config = load_config(None, dict(
        model="rdpd", width=0.125, synthetic_data=str(tiny_synthetic_dataset), patch_size=32,
        sequence_batch=1, sequence_frames=2, synthetic_as_frames=True, epochs=1,
        iterations_per_epoch=1, workers=0, tensorboard=False))
    train(config, tmp_path / "run", progress=False)
    model = load_model(tmp_path / "run" / "last.safetensors")
    assert model.temporal is False
    rng = np.random.default_rng(2)
    frames = [{"left": rng.random((30, 44, 3), dtype=np.float32),
               "right": rng.random((30, 44, 3), dtype=np.float32)} for _ in range(2)]
    outputs = deblur_sequence(model, frames, precision="fp32")
    np.testing.assert_array_equal(outputs[1], Deblurrer(model, precision="fp32")(frames[1]["left"],
                                                                frames[1]["right"]))
    save_model(tmp_path / "copy.safetensors", model)  # the flag survives export
    assert load_model(tmp_path / "copy.safetensors").temporal is False
    assert build_model("rdpd", width=0.125).temporal is True


@pytest.mark.parametrize("name", ["tiny_model", "refined_model"])
def test_onnx_matches_pytorch(name, tmp_path, request):
    pytest.importorskip("onnxruntime")
    tiny_model = request.getfixturevalue(name)
    from dualpixel.inference.onnx_export import export_onnx, run_onnx, state_shape

    h, w = 40, 56
    export_onnx(tiny_model, tmp_path / "frame.onnx", height=h, width=w)
    export_onnx(tiny_model, tmp_path / "step.onnx", height=h, width=w, step=True)
    x1, x2 = torch.rand(2, 1, 7, h, w)
    with torch.no_grad():
        y1, state = tiny_model.step(x1)
        y2, _ = tiny_model.step(x2, state)
    (frame,) = run_onnx(tmp_path / "frame.onnx", x1.numpy())
    assert np.abs(frame - y1.numpy()).max() < 1e-4
    zeros = np.zeros(state_shape(tiny_model, h, w), np.float32)
    out1, hidden, cell = run_onnx(tmp_path / "step.onnx", x1.numpy(), zeros, zeros)
    out2, _, _ = run_onnx(tmp_path / "step.onnx", x2.numpy(), hidden, cell)
    assert np.abs(out1 - y1.numpy()).max() < 1e-4
    assert np.abs(out2 - y2.numpy()).max() < 1e-4
    # exported at 40x56, run at another size (not a multiple of 16): height and width are dynamic
    x3 = torch.rand(1, 7, 66, 90)
    with torch.no_grad():
        y3, state3 = tiny_model.step(x3)
        y4, _ = tiny_model.step(x3, state3)
    (frame3,) = run_onnx(tmp_path / "frame.onnx", x3.numpy())
    assert frame3.shape == (1, 3, 66, 90) and np.abs(frame3 - y3.numpy()).max() < 1e-4
    zeros3 = np.zeros(state_shape(tiny_model, 66, 90), np.float32)
    _, hidden3, cell3 = run_onnx(tmp_path / "step.onnx", x3.numpy(), zeros3, zeros3)
    out4, _, _ = run_onnx(tmp_path / "step.onnx", x3.numpy(), hidden3, cell3)
    assert np.abs(out4 - y4.numpy()).max() < 1e-4
    # exported at multiples of 16 (as `export` does by default, 512x512): the padding is still in
    # the graph, so sides that are not multiples of 16 (1920x1080 has 1080) run
    export_onnx(tiny_model, tmp_path / "even.onnx", height=48, width=64)
    (frame5,) = run_onnx(tmp_path / "even.onnx", x3.numpy())
    assert frame5.shape == (1, 3, 66, 90) and np.abs(frame5 - y3.numpy()).max() < 1e-4


def test_flip_ensemble_is_equivariant_to_the_dp_flips(tiny_model):
    # Averaging over the flips that keep DP geometry makes the output flip with the input:
    # upside down, and left-right with the views swapped. A single pass does not.
    rng = np.random.default_rng(3)
    left, right = (rng.random((48, 64, 3), dtype=np.float32) for _ in range(2))
    ensemble, single = Deblurrer(tiny_model, **FP32, flips=True), Deblurrer(tiny_model, **FP32)

    def first_frame(deblurrer, *views):  # a recurrent model: each call a new sequence
        deblurrer.reset()
        return deblurrer(*views)

    out = first_frame(ensemble, left, right)
    np.testing.assert_allclose(first_frame(ensemble, left[::-1], right[::-1]), out[::-1],
                               atol=1e-6)
    np.testing.assert_allclose(first_frame(ensemble, right[:, ::-1], left[:, ::-1]),
                               out[:, ::-1], atol=1e-6)
    plain = first_frame(single, left, right)
    flipped = first_frame(single, right[:, ::-1], left[:, ::-1])
    assert np.abs(flipped - plain[:, ::-1]).max() > 1e-3
    # It is the mean of the four passes, so it lies within their range, not equal to the plain one.
    assert np.abs(out - plain).max() > 1e-4


def test_flip_ensemble_of_a_single_view_model_flips_upside_down_only():
    torch.manual_seed(0)
    model = build_model("rspd", width=0.125).eval()
    rng = np.random.default_rng(4)
    left = rng.random((32, 48, 3), dtype=np.float32)
    out = Deblurrer(model, precision="fp32", flips=True)(left)
    flipped = Deblurrer(model, **FP32, flips=True)(left[::-1])
    np.testing.assert_allclose(flipped, out[::-1], atol=1e-6)
    manual = (Deblurrer(model, **FP32)(left)
              + Deblurrer(model, **FP32)(left[::-1].copy())[::-1]) / 2
    np.testing.assert_allclose(out, manual, atol=1e-6)


def test_flip_ensemble_members_carry_their_own_state(tiny_model):
    rng = np.random.default_rng(5)
    frames = [[rng.random((32, 48, 3), dtype=np.float32) for _ in range(2)] for _ in range(2)]
    ensemble = Deblurrer(tiny_model, precision="fp32", flips=True)
    got = [ensemble(left, right) for left, right in frames]
    members = [  # each member: the whole sequence flipped, through its own plain Deblurrer
        (lambda a, b: (a, b), lambda o: o),
        (lambda a, b: (a[::-1], b[::-1]), lambda o: o[::-1]),
        (lambda a, b: (b[:, ::-1], a[:, ::-1]), lambda o: o[:, ::-1]),
        (lambda a, b: (b[::-1, ::-1], a[::-1, ::-1]), lambda o: o[::-1, ::-1]),
    ]
    expected = np.zeros((2, 32, 48, 3), np.float32)
    for flip, unflip in members:
        plain = Deblurrer(tiny_model, precision="fp32")
        for index, (left, right) in enumerate(frames):
            expected[index] += unflip(plain(*flip(left, right))) / 4
    np.testing.assert_allclose(np.stack(got), expected, atol=1e-6)


def test_fuse_scales_takes_fine_detail_from_one_and_coarse_structure_from_the_other():
    height, width = 64, 96
    ys, xs = np.mgrid[:height, :width].astype(np.float32)
    checker = 0.5 + 0.1 * ((ys + xs) % 2 * 2 - 1)  # the finest detail there is, mean 0.5
    ramp = (0.3 + 0.4 * xs / width)[..., None].repeat(3, -1)  # coarse structure only
    fine = np.repeat(checker[..., None], 3, -1)
    coarse = cv2.resize(ramp, (width // 2, height // 2), interpolation=cv2.INTER_AREA)
    fused = fuse_scales(fine, coarse, sigma=3.0)
    # The fused image's detail is the fine input's; its local mean is the coarse input's ramp.
    detail = fused - cv2.GaussianBlur(fused, (0, 0), 3.0)
    np.testing.assert_allclose(detail, fine - cv2.GaussianBlur(fine, (0, 0), 3.0), atol=0.02)
    local_mean = cv2.blur(fused, (2, 2))[8:-8, 8:-8]  # the checker averages out over 2x2
    np.testing.assert_allclose(local_mean, cv2.blur(ramp, (2, 2))[8:-8, 8:-8], atol=0.01)
    # Where the coarse input is the fine one, downsampled, a smooth image comes back unchanged.
    np.testing.assert_allclose(fuse_scales(ramp, coarse), ramp, atol=2e-3)
    with pytest.raises(ParameterError, match="sigma must be > 0"):
        fuse_scales(fine, coarse, sigma=0.0)


def test_multiscale_fuses_a_half_resolution_pass_with_its_own_state(tiny_model):
    rng = np.random.default_rng(6)
    frames = [[rng.random((64, 96, 3), dtype=np.float32) for _ in range(2)] for _ in range(2)]
    two_scale = Deblurrer(tiny_model, precision="fp32", multiscale=True)
    # one sequence per scale
    fine, coarse = Deblurrer(tiny_model, **FP32), Deblurrer(tiny_model, **FP32)
    for left, right in frames:  # the second frame uses the states carried from the first
        expected = fuse_scales(fine(left, right),
                               coarse(half_resolution(left), half_resolution(right)))
        np.testing.assert_allclose(two_scale(left, right), expected, atol=1e-6)
    assert np.abs(expected - fine(*frames[0])).max() > 1e-3  # the fusion changed something
    # With the flips, the output still flips with the input (the scales commute with them).
    both = Deblurrer(tiny_model, precision="fp32", flips=True, multiscale=True)
    out = both(*frames[0])
    both.reset()
    mirrored = both(frames[0][1][:, ::-1], frames[0][0][:, ::-1])
    np.testing.assert_allclose(mirrored, out[:, ::-1], atol=1e-5)
    two_scale.reset()
    with pytest.raises(ParameterError, match="at least 32x32 px, got 40x20"):
        two_scale(np.zeros((20, 40, 3), np.float32), np.zeros((20, 40, 3), np.float32))
    with pytest.raises(ParameterError, match="sigma must be > 0"):
        Deblurrer(tiny_model, precision="fp32", multiscale=True, fusion_sigma=-1.0)


def test_onnx_matches_pytorch_for_naf_levels(naf_model, tmp_path):
    pytest.importorskip("onnxruntime")
    from dualpixel.inference.onnx_export import export_onnx, run_onnx

    export_onnx(naf_model, tmp_path / "naf.onnx", height=48, width=64)
    x = torch.rand(1, 7, 40, 56)  # another size than traced
    with torch.no_grad():
        expected, _ = naf_model.step(x)
    (out,) = run_onnx(tmp_path / "naf.onnx", x.numpy())
    assert np.abs(out - expected.numpy()).max() < 1e-4
    assert np.abs(out - (x[:, :3] + x[:, 3:6]).numpy() / 2).mean() > 1e-3  # not the input
