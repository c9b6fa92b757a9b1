"""Issue #77 item 4: how far does a model look, in effect, on real DP views?

For points on a grid of each scene (``scene_*/view0.png``, ``view1.png``), the gradient of the
output's mean over the three colours at that pixel with respect to both views, on a crop around
the point; the radii (px) holding 50 % and 90 % of its absolute mass (Luo et al. 2016's
effective receptive field, which is usually far smaller than the theoretical one), beside the
point's defocus disparity (the horizontal shift that best aligns the two views' grey levels in
a ``--window``-px window; DP disparity grows with the blur radius) and the window's standard
deviation of grey (flat windows give no disparity; the bins count textured points only, at
least ``--min-texture``). Medians per scene and by disparity bin.

    python experiments/scripts/effective_reach.py rdpd-light.v18 ../shared/data/canon-dp-real-hd
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from dualpixel import load_model
from dualpixel.data.radial import radial_distance
from dualpixel.io.images import read_rgb


def mass_radii(grad: np.ndarray, centre: tuple[int, int]) -> tuple[float, float]:
    """Radii around ``centre`` holding 50 % and 90 % of the mass of ``grad`` ``(H, W)``."""
    yy, xx = np.indices(grad.shape)
    radius = np.hypot(yy - centre[0], xx - centre[1]).ravel()
    order = np.argsort(radius)
    mass = np.cumsum(grad.ravel()[order])
    mass /= mass[-1]
    return (float(radius[order][np.searchsorted(mass, 0.5)]),
            float(radius[order][np.searchsorted(mass, 0.9)]))


def disparity(left: np.ndarray, right: np.ndarray, centre: tuple[int, int], window: int,
              most: int = 24) -> tuple[int, float]:
    """The shift ``d`` (px, |d| <= ``most``) minimising the mean squared difference of the
    left view's window at ``centre`` and the right view's shifted by ``d``, and the window's
    standard deviation; grey ``(H, W)``."""
    y, x = centre
    half = window // 2
    patch = left[y - half:y + half, x - half:x + half]
    costs = [np.mean((patch - right[y - half:y + half, x - half + d:x + half + d]) ** 2)
             for d in range(-most, most + 1)]
    return int(np.argmin(costs)) - most, float(patch.std())


def scene_radii(net, folder: Path, crop: int, grid: int,
                window: int) -> list[tuple[float, float, int, float]]:
    """The mass radii, disparity and texture at a ``grid`` x ``grid`` of points of one
    scene."""
    views = [torch.from_numpy(read_rgb(folder / f"view{i}.png")).permute(2, 0, 1)[None].float()
             for i in (0, 1)]
    height, width = views[0].shape[-2:]
    radial = torch.from_numpy(radial_distance(height, width))[None, None]
    grey = [v[0].mean(0).numpy() for v in views]
    half = crop // 2
    radii = []
    for y in np.linspace(half, height - half, grid).astype(int):
        for x in np.linspace(half, width - half, grid).astype(int):
            around = (..., slice(y - half, y + half), slice(x - half, x + half))
            left, right = (v[around].clone().requires_grad_(True) for v in views)
            out, _ = net.step(net.spec.make_input(left, right, radial[around]))
            out[0, :, half, half].mean().backward()
            grad = (left.grad.abs() + right.grad.abs())[0].sum(0).numpy()
            radii.append((*mass_radii(grad, (half, half)),
                          *disparity(*grey, (y, x), window)))
    return radii


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", help="a shipped tag or a .safetensors file")
    parser.add_argument("scenes", type=Path, help="folder of scene_*/view0.png, view1.png")
    parser.add_argument("--crop", type=int, default=384, help="crop around each point (px)")
    parser.add_argument("--grid", type=int, default=3, help="points per side of each scene")
    parser.add_argument("--window", type=int, default=96, help="disparity window (px)")
    parser.add_argument("--min-texture", type=float, default=0.03,
                        help="least grey standard deviation of a binned point's window")
    args = parser.parse_args()
    net = load_model(args.checkpoint, device="cpu").eval()
    every = []
    for folder in sorted(args.scenes.glob("scene_*")):
        radii = np.array(scene_radii(net, folder, args.crop, args.grid, args.window))
        every.append(radii)
        print(f"{folder.name}: 50 % within {np.median(radii[:, 0]):.1f} px, "
              f"90 % within {np.median(radii[:, 1]):.1f} px", flush=True)
    radii = np.concatenate(every)
    print(f"all {len(radii)} points: 50 % within {np.median(radii[:, 0]):.1f} px, 90 % within "
          f"{np.median(radii[:, 1]):.1f} px (90 % range {radii[:, 1].min():.1f}-"
          f"{radii[:, 1].max():.1f})")
    shift = np.abs(radii[:, 2])
    textured = radii[:, 3] >= args.min_texture
    print(f"{int(textured.sum())} textured points (grey std >= {args.min_texture})")
    for low, high in ((0, 2), (2, 5), (5, 10), (10, 25)):
        inside = radii[textured & (shift >= low) & (shift < high)]
        if len(inside):
            print(f"|disparity| {low}-{high - 1} px: {len(inside)} points, 50 % within "
                  f"{np.median(inside[:, 0]):.1f} px, 90 % within {np.median(inside[:, 1]):.1f}")


if __name__ == "__main__":
    main()
