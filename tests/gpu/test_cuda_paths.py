"""Every path that runs differently on a GPU, against the CPU: inference precisions, the
renderers, a training crop's window, training with frames rendered on the device."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dualpixel import deblur
from dualpixel.optics.thin_lens import PAPER_LENS_SETS, coc_radius
from dualpixel.synthesis.batched_renderer import render_batch
from dualpixel.synthesis.frame import draw_sequence, synthesize_frame
from dualpixel.synthesis.renderer import render_dp_views
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence


def _host(value) -> torch.Tensor:
    """A tensor (on any device) or an array, as float64 on the CPU."""
    if isinstance(value, torch.Tensor):
        return value.detach().to("cpu", torch.float64)
    return torch.as_tensor(np.asarray(value), dtype=torch.float64)


def _psnr(a, b) -> float:
    a, b = _host(a), _host(b)
    return float(10 * torch.log10(1.0 / ((a - b) ** 2).mean().clamp_min(1e-20)))


@pytest.fixture(scope="module")
def frame():
    rgb, depth = render_scene_sequence(5, SceneConfig(width=256, height=176, frames=1,
                                                      leaves=12))[0]
    return rgb, depth


@pytest.fixture(scope="module")
def views(frame):
    rgb, depth = frame
    result = synthesize_frame(rgb, depth, draw_sequence(3, "set2", noise=False))
    return tuple(v.permute(1, 2, 0).numpy() for v in (result.left, result.right))


@pytest.mark.parametrize("precision", ["auto", "fp16", "fp32"])
def test_the_default_deblurs_on_the_gpu_as_on_the_cpu(gpu, views, precision):
    """The shipped default (tied), every precision on the device, against float32 on the CPU."""
    if precision == "fp16" and gpu.type != "cuda":
        pytest.skip("fp16 runs on CUDA only")
    reference = deblur(*views, device="cpu", precision="fp32")
    on_device = deblur(*views, device=str(gpu), precision=precision)
    assert on_device.shape == reference.shape and on_device.dtype == np.float32
    assert _psnr(on_device, reference) > (60 if precision == "fp32" else 40)
    assert float(np.abs(on_device - reference).max()) < 8 / 255


def test_the_renderers_on_the_gpu_are_the_cpu_renderers(gpu, frame):
    """The default renderer (torch convolutions there, OpenCV here) and the batched renderer
    on the device, against the default renderer on the CPU."""
    rgb, depth = frame
    image = torch.from_numpy(rgb).permute(2, 0, 1)
    coc = coc_radius(torch.from_numpy(depth), PAPER_LENS_SETS["set4"])  # reduced resolutions too
    cpu = render_dp_views(image, coc)
    default = render_dp_views(image.to(gpu), coc.to(gpu))
    batched = render_batch(image[None].to(gpu), coc[None].to(gpu))
    for view in range(2):
        assert _psnr(default[view], cpu[view]) > 70
        assert _psnr(batched[view][0], cpu[view]) > 70


def test_a_window_renders_on_the_gpu_as_on_the_cpu(gpu, frame):
    """A training crop's window (distortion, noise drawn by the device's generator: compared
    without noise) on the device, against the CPU's window."""
    rgb, depth = frame
    draw = draw_sequence(7, "set0", noise=False)
    window = (37, 101, 64, 96)
    cpu = synthesize_frame(rgb, depth, draw, window=window)
    device = synthesize_frame(rgb, depth, draw, window=window, device=str(gpu))
    for name in ("left", "right", "combined", "target"):
        assert _psnr(getattr(device, name), getattr(cpu, name)) > 70, name


@pytest.mark.parametrize("workers", [0, 1])
def test_training_renders_its_frames_on_the_gpu(gpu, tmp_path, workers):
    """Two iterations with on-the-fly frames rendered on the device (`render_on: device`) in
    the training process, or by a (spawned) loader process, bfloat16 autocast where the device
    has it: finite losses, weights written."""
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
    from dualpixel.synthesis.on_the_fly import write_on_the_fly
    from dualpixel.synthesis.scenes import write_scene_folder
    from dualpixel.training import load_config, train

    settings = SynthConfig(lens_sets=("dslr-840",), psf_bank="pixel4", bit_depth=8, seed=2)
    write_scene_folder(tmp_path / "scenes", 4, SceneConfig(width=192, height=128, frames=1,
                                                           layout="photo"), progress=False)
    write_on_the_fly(tmp_path / "fly", tmp_path / "scenes", "rgbd", settings)
    synthesize_dataset(tmp_path / "scenes", "rgbd", tmp_path / "val",
                       SynthConfig(lens_sets=("dslr-840",), bit_depth=8, seed=3), progress=False)
    config = load_config(None, dict(
        model="rdpd", width=0.25, residual=True, synthetic_data=str(tmp_path / "fly"),
        synthetic_as_frames=True, val_data=str(tmp_path / "val"), val_split="train",
        patch_size=64, sequence_batch=2, sequence_frames=1, epochs=1, iterations_per_epoch=2,
        workers=workers, device=str(gpu), render_on="device", tensorboard=False))
    result = train(config, tmp_path / "run", progress=False)
    assert result.step == 2 and np.isfinite(result.history[-1]["loss"])
    assert (tmp_path / "run" / "last.safetensors").is_file()
