"""Time one 1920x1080 frame: our layered renderer against the naive approach, in one run.

Naive (the authors' generator): for every distinct CoC, filter the *whole frame* once per view,
then hard-mask the layer's pixels (no occlusion compositing). Ours composites back to front with
blurred masks and works only inside each layer's support. Prints seconds per frame and the ratio.

    .venv/bin/python benchmarks/bench_synthesis.py [--device cuda] [--layers 500]
"""

from __future__ import annotations

import argparse
import resource
import time

import torch

from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.optics.thin_lens import CAMERA_PRESETS, coc_radius
from dualpixel.synthesis.convolution import convolve_same
from dualpixel.synthesis.renderer import quantise_layers, render_dp_views
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence


def naive_render(image: torch.Tensor, coc: torch.Tensor, params: PSFParams, max_layers: int):
    labels, layer_coc = quantise_layers(coc, max_layers)
    left = torch.empty_like(image)
    right = torch.empty_like(image)
    for index, radius in enumerate(layer_coc.tolist()):
        kernels = 2.0 * torch.stack(list(dp_psf(radius, params, device=image.device)))
        blurred = convolve_same(image, kernels)
        mask = labels == index
        left[:, mask] = blurred[0][:, mask]
        right[:, mask] = blurred[1][:, mask]
    return left, right


def _timed(fn, device: str) -> float:
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    start = time.perf_counter()
    fn()
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--layers", type=int, default=500)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--full-range", action="store_true",
                        help="replace the scene's depth by a ramp over every CoC: all layers used")
    args = parser.parse_args()

    rgb, depth = render_scene_sequence(0, SceneConfig(width=args.width, height=args.height,
                                                      frames=1, leaves=40))[0]
    if args.full_range:
        import numpy as np

        ramp = np.geomspace(0.3, 200.0, args.width * args.height, dtype=np.float32)
        depth = ramp.reshape(args.height, args.width)
    image = torch.from_numpy(rgb).permute(2, 0, 1).to(args.device)
    coc = coc_radius(torch.from_numpy(depth).to(args.device), CAMERA_PRESETS["set2"])
    params = PSFParams(n=6, alpha=0.6, beta=0.2)
    layers = quantise_layers(coc, args.layers)[1].numel()
    print(f"frame {args.width}x{args.height} on {args.device}, {layers} layers, "
          f"CoC {float(coc.min()):.1f}..{float(coc.max()):.1f} px, torch threads "
          f"{torch.get_num_threads()}")
    ours = _timed(lambda: render_dp_views(image, coc, params, max_layers=args.layers), args.device)
    print(f"ours (occlusion-aware, per-layer support): {ours:.2f} s/frame")
    naive = _timed(lambda: naive_render(image, coc, params, args.layers), args.device)
    print(f"naive (whole frame per layer, hard mask):  {naive:.2f} s/frame")
    print(f"ratio ours / naive: {ours / naive:.2f}")
    frame_mib = image.numel() * image.element_size() / 2**20
    print(f"peak process memory (both renderers): "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB "
          f"(one float32 RGB frame is {frame_mib:.0f} MiB)")
    if args.device.startswith("cuda"):
        print(f"peak GPU memory: {torch.cuda.max_memory_allocated() / 2**20:.0f} MiB")


if __name__ == "__main__":
    main()
