"""The top-level API as a notebook uses it: arrays in, the same kind of arrays out."""

import subprocess
import sys

import numpy as np
import pytest
import torch

import dualpixel


def scene(height=48, width=64):
    rng = np.random.default_rng(0)
    rgb = np.clip(rng.random((height, width, 3)) * 0.8 + 0.1, 0, 1)
    depth = np.where(np.arange(width)[None, :] < width // 2, 2.0, 8.0) * np.ones((height, 1))
    return rgb, depth


def test_synthesise_deblur_and_score_with_numpy():
    rgb, depth = scene()
    frame = dualpixel.synthesize(rgb, depth, lens_set="dslr-840", seed=3)
    assert frame["left"].shape == rgb.shape and isinstance(frame["left"], np.ndarray)
    assert frame["defocus"].shape == depth.shape
    # a defocus profile focuses at the depth map's 30th percentile: the near half (2 m) is sharp
    near = depth == 2.0
    assert np.abs(frame["defocus"][near]).max() < 0.05 < np.abs(frame["defocus"][~near]).min()
    model = dualpixel.load_model("rdpd-light")  # by name, from the package
    sharp = dualpixel.deblur(frame["left"], frame["right"], model=model, device="cpu")
    assert sharp.shape == rgb.shape and sharp.dtype == np.float32
    assert 0 <= sharp.min() and sharp.max() <= 1
    error = sharp.astype(np.float64) - frame["target"]  # the metrics' known answers
    assert dualpixel.psnr(sharp, frame["target"]) == pytest.approx(
        10 * np.log10(1 / np.mean(error**2)), abs=1e-4)
    assert dualpixel.mae(sharp, frame["target"]) == pytest.approx(np.mean(np.abs(error)), abs=1e-6)
    assert dualpixel.ssim(frame["target"], frame["target"]) == pytest.approx(1.0)
    assert dualpixel.ssim(sharp, frame["target"]) < 1.0
    # integer images by their range: the same result as the float ones
    as_uint8 = [np.rint(frame[k] * 255).astype(np.uint8) for k in ("left", "right")]
    from_uint8 = dualpixel.deblur(*as_uint8, model=model, device="cpu")
    from_float = dualpixel.deblur(*(a / 255.0 for a in as_uint8), model=model, device="cpu")
    np.testing.assert_allclose(from_uint8, from_float, atol=1e-6)


def test_torch_in_torch_out_and_batches_are_independent_pairs():
    rgb, depth = scene()
    tensor = torch.from_numpy(rgb).permute(2, 0, 1).float()
    frame = dualpixel.synthesize(tensor, torch.from_numpy(depth), lens_set="set1", seed=1)
    assert isinstance(frame["left"], torch.Tensor) and frame["left"].shape == (3, 48, 64)
    single = dualpixel.deblur(frame["left"], frame["right"], device="cpu")
    assert isinstance(single, torch.Tensor) and single.shape == (3, 48, 64)
    batch = dualpixel.deblur(torch.stack([frame["left"]] * 2), torch.stack([frame["right"]] * 2),
                             device="cpu")
    assert batch.shape == (2, 3, 48, 64)
    torch.testing.assert_close(batch[1], single)  # no state carried from pair 0 to pair 1
    numpy_out = dualpixel.deblur(frame["left"].permute(1, 2, 0).numpy(),
                                 frame["right"].permute(1, 2, 0).numpy(), device="cpu")
    np.testing.assert_allclose(single.permute(1, 2, 0).numpy(), numpy_out, atol=1e-6)


def test_every_function_takes_every_layout_alike():
    """Issue #33: NumPy (H, W, C) / grey / RGBA, PIL, torch (C, H, W) / (N, C, H, W) give the same
    numbers in every top-level function; a batch scores as the mean of its images."""
    from PIL import Image

    rgb, depth = scene()
    frame = dualpixel.synthesize(rgb, depth, lens_set="set1", seed=2)
    left8 = np.rint(frame["left"] * 255).astype(np.uint8)
    right8 = np.rint(frame["right"] * 255).astype(np.uint8)
    target8 = np.rint(frame["target"] * 255).astype(np.uint8)
    chw = lambda a: torch.from_numpy(a).permute(2, 0, 1)  # noqa: E731
    rgba = lambda a: np.dstack([a, np.full(a.shape[:2], 255, np.uint8)])  # noqa: E731
    layouts = {
        "numpy": (left8, right8, target8),
        "pil": tuple(Image.fromarray(a) for a in (left8, right8, target8)),
        "pil-rgba": tuple(Image.fromarray(rgba(a)) for a in (left8, right8, target8)),
        "rgba": (rgba(left8), rgba(right8), rgba(target8)),
        "torch": (chw(left8), chw(right8), chw(target8)),
        "torch-float": tuple(chw(a).float() / 255 for a in (left8, right8, target8)),
    }
    expected = {name: fn(left8, target8) for name, fn in
                (("psnr", dualpixel.psnr), ("ssim", dualpixel.ssim), ("mae", dualpixel.mae))}
    expected["niqe"] = dualpixel.niqe(np.tile(left8, (2, 2, 1)))
    sharp = dualpixel.deblur(left8, right8, device="cpu", precision="fp32")
    findings = dualpixel.check_views(left8, right8, target8)
    for name, (left, right, target) in layouts.items():
        for metric, value in expected.items():
            if metric == "niqe":
                got = dualpixel.niqe(np.tile(np.asarray(left), (2, 2, 1)) if "pil" in name else
                                     (left.repeat(1, 2, 2) if "torch" in name else
                                      np.tile(left, (2, 2, 1))))
            else:
                got = getattr(dualpixel, metric)(left, target)
            assert got == pytest.approx(value, rel=1e-6, abs=1e-6), (name, metric)
        out = dualpixel.deblur(left, right, device="cpu", precision="fp32")
        as_hwc = out.permute(1, 2, 0).numpy() if isinstance(out, torch.Tensor) else out
        np.testing.assert_allclose(as_hwc, sharp, atol=1e-5, err_msg=name)
        assert dualpixel.check_views(left, right, target) == findings, name
    grey = left8[..., 1]
    assert dualpixel.psnr(grey, target8[..., 1]) == pytest.approx(
        dualpixel.psnr(np.dstack([grey] * 3), np.dstack([target8[..., 1]] * 3)))
    assert dualpixel.deblur(grey, right8[..., 1], device="cpu").shape == (48, 64)  # grey kept
    batch = torch.stack([chw(left8), chw(target8)])
    assert dualpixel.ssim(batch, torch.stack([chw(target8)] * 2)) == pytest.approx(
        (expected["ssim"] + 1.0) / 2)
    with pytest.raises(ValueError, match=r"np.moveaxis"):
        dualpixel.psnr(left8.transpose(2, 0, 1), target8.transpose(2, 0, 1))


def test_synthesise_with_a_calibrated_camera(tmp_path):
    """A calibrated camera as `synth --camera` takes it: its per-channel disparity ratio forms
    the views and its light space is where the blur happens; a camera.json path and the
    DPCamera give the same frame."""
    from dualpixel.calibration.camera import DPCamera
    from dualpixel.errors import InputFileError
    from dualpixel.optics.psf import PSFParams

    rgb, depth = scene()
    psf = PSFParams(n=3.0, alpha=0.45, beta=0.2, kappa=0.21)
    paper = DPCamera("paper", 64, (1.0, 1.0, 1.0), psf)
    weak_red = DPCamera("weak-red", 64, (0.4, 1.0, 1.0), psf)
    path = weak_red.save(tmp_path / "camera.json")
    common = dict(lens_set="set1", seed=4, noise=False, distortion=False)
    full = dualpixel.synthesize(rgb, depth, camera=paper, **common)
    from_file = dualpixel.synthesize(rgb, depth, camera=path, **common)
    from_object = dualpixel.synthesize(rgb, depth, camera=weak_red, **common)
    for key in ("left", "right", "combined", "target", "defocus"):
        np.testing.assert_array_equal(from_file[key], from_object[key])

    def disparity(frame, channel):
        return np.abs(frame["left"][..., channel] - frame["right"][..., channel]).mean()

    assert disparity(full, 0) > 1e-3
    assert disparity(from_file, 0) == pytest.approx(0.4 * disparity(full, 0), rel=0.02)
    assert disparity(from_file, 1) == pytest.approx(disparity(full, 1), rel=1e-4)
    linear = dualpixel.synthesize(rgb, depth, camera=path, light="linear", **common)
    assert np.abs(linear["left"] - from_file["left"]).max() > 1e-3
    with pytest.raises(ValueError, match=r"psf_shapes .* needs a camera"):
        dualpixel.synthesize(rgb, depth, psf_shapes="bank")
    with pytest.raises(ValueError, match="light must be one of"):
        dualpixel.synthesize(rgb, depth, camera=path, light="log")
    with pytest.raises(InputFileError, match=r"missing\.json"):
        dualpixel.synthesize(rgb, depth, camera=tmp_path / "missing.json")
    with pytest.raises(ValueError, match=r"camera must be a shipped camera's name, a camera\.json"):
        dualpixel.synthesize(rgb, depth, camera={"name": "x"})
    # the old meanings, for one more release: camera= naming a lens set, camera_file=
    with pytest.warns(FutureWarning, match=r"lens set is now lens_set="):
        old = dualpixel.synthesize(rgb, depth, camera="set1", seed=4, noise=False,
                                   distortion=False)
    np.testing.assert_array_equal(old["left"],
                                  dualpixel.synthesize(rgb, depth, **common)["left"])
    with pytest.warns(FutureWarning, match=r"camera_file=\.\.\.\) is now camera="):
        old = dualpixel.synthesize(rgb, depth, camera_file=path, **common)
    np.testing.assert_array_equal(old["left"], from_file["left"])


def test_a_numpy_batch_comes_back_a_batch_of_the_same_results():
    """NumPy ``(N, H, W, C)``, as the README lists it: each image as if given alone."""
    rgb, _ = scene(32, 48)
    left, right = rgb[None].repeat(2, 0).astype(np.float32), rgb[None].repeat(2, 0)
    right = np.clip(right[:, :, ::-1] * np.array([1.0, 0.9])[:, None, None, None], 0, 1)
    right = right.astype(np.float32)
    out = dualpixel.deblur(left, right, device="cpu")
    assert out.shape == left.shape and out.dtype == np.float32
    for k in range(2):
        np.testing.assert_allclose(out[k], dualpixel.deblur(left[k], right[k], device="cpu"),
                                   atol=1e-5)


def test_clear_errors_and_the_listing():
    rgb, depth = scene()
    with pytest.raises(ValueError, match=r"left .* and right .* differ"):
        dualpixel.deblur(rgb, rgb[:10])
    with pytest.raises(ValueError, match=r"float values must lie in \[0, 1\]"):
        dualpixel.deblur(rgb * 255, rgb * 255)
    with pytest.raises(ValueError, match="lens_set must be one of"):
        dualpixel.synthesize(rgb, depth, lens_set="set9")
    # depth as the README gives it: (H, W) or (H, W, 1); channels that differ are an encoding
    one = dualpixel.synthesize(rgb, depth, seed=4)["left"]
    np.testing.assert_array_equal(dualpixel.synthesize(rgb, depth[..., None], seed=4)["left"], one)
    encoded = np.dstack([depth, depth * 2, depth])
    with pytest.raises(ValueError, match="depth has 3 channels that differ"):
        dualpixel.synthesize(rgb, encoded)
    for seed, problem in ((-1, r"in \[0, 2\*\*63 - 1\]"), (2**63, r"in \[0, 2\*\*63 - 1\]"),
                          (1.5, "an integer"), (True, "an integer")):
        with pytest.raises(ValueError, match=f"seed must be {problem}"):
            dualpixel.synthesize(rgb, depth, seed=seed)
    with pytest.raises(ValueError, match="checkpoint not found"):
        dualpixel.load_model("no-such-model")
    from dualpixel.models import load_model as load_file  # the file loader, given a name

    with pytest.raises(ValueError, match=r"shipped model's name: dualpixel\.load_model"):
        load_file("rdpd-light")
    models = dualpixel.list_models()
    assert {"rdpd-light.v15", "rdpd-light.v16", "rdpd-light.v18"} <= set(models)
    info = models["rdpd-light.v18"]
    assert "rdpd-light" in info["aliases"]
    assert models["rdpd-light.v15"]["aliases"] == []  # kept by its tag: v16's start
    for retired in ("rdpd-wide", "rdpd-wide.v2"):  # the recipe that remakes it named
        with pytest.raises(ValueError, match=rf"{retired} no longer ships.*recipes/rdpd-wide"):
            dualpixel.load_model(retired)
    with pytest.raises(ValueError, match=r"rdpd-light-fast no longer ships.*use rdpd-light"):
        dualpixel.load_model("rdpd-light-fast")
    assert info["parameters"] > 1_000_000 and len(info["sha256"]) == 64
    assert set(dualpixel.__all__) >= {"deblur", "synthesize", "load_model", "list_models", "psnr"}


def test_list_models_reads_headers_without_torch():
    code = ("import sys, dualpixel; models = dualpixel.list_models(); "
            "print('torch' in sys.modules, sorted(models))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("False [")


def test_import_is_light():
    code = "import sys, dualpixel; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_registry_ships_its_model_card():
    from dualpixel.weights import model_card

    assert "# Model card" in model_card() and "canon" in model_card().lower()


def test_the_guides_first_example_gains_with_the_shipped_model():
    """`synthesize()` starts from what the shipped model was trained on, so the guide's first
    example (synthesize, then deblur with the default) improves the frame; with the paper's
    settings (noise about six times a real photograph's) it need not."""
    from dualpixel.synthesis.scenes import SceneConfig, render_scene

    (rgb, depth), = render_scene(7, SceneConfig(width=336, height=224, frames=1,
                                                layout="photo"))[0]
    frame = dualpixel.synthesize(rgb, depth, seed=0)
    sharp = dualpixel.deblur(frame["left"], frame["right"], device="cpu")
    gain = dualpixel.psnr(sharp, frame["target"]) - dualpixel.psnr(frame["combined"],
                                                                    frame["target"])
    assert gain > 0.5, gain
    # the paper's settings, one option away: its set1 unless a lens set is named
    paper = dualpixel.synthesize(rgb, depth, seed=0, settings="paper")
    np.testing.assert_array_equal(paper["left"], dualpixel.synthesize(
        rgb, depth, seed=0, settings="paper", lens_set="set1")["left"])


def test_a_sequence_carries_a_temporal_models_state():
    from dualpixel.models import build_model

    torch.manual_seed(0)
    model = build_model("rdpd", width=0.125).eval()
    rng = np.random.default_rng(4)
    lefts, rights = (rng.random((3, 32, 48, 3), dtype=np.float32) for _ in range(2))
    apart = dualpixel.deblur(lefts, rights, model=model, device="cpu", precision="fp32")
    carried = dualpixel.deblur(lefts, rights, model=model, device="cpu", precision="fp32",
                               sequence=True)
    np.testing.assert_array_equal(carried[0], apart[0])  # the first frame starts from zero
    for later in (1, 2):  # the later ones see the state of the frames before them
        assert np.abs(carried[later] - apart[later]).max() > 1e-4
    model.temporal = False  # a model trained on single frames runs every frame afresh
    np.testing.assert_array_equal(
        dualpixel.deblur(lefts, rights, model=model, device="cpu", precision="fp32",
                         sequence=True), apart)
