"""Issue #77 item 3: how real DP views depart from our formation across the field.

On the dev Canon scenes (840 px; targets read), per 48-px block: the CoC radius and signed
disparity ratio of the target-calibrated fit (:func:`dualpixel.calibration.camera.fit_blocks`,
the Canon camera file's PSF shape, linear light), the distance from the frame's centre (a
fraction of the half-diagonal) and the default model's PSNR gain over the input. Prints the gain
by radius and field zone, and the disparity ratio by zone; writes the figure of estimated kernels
(nearest and farthest blocks from the centre blurred by at least 5 px).

Then, to tell what of it our formation would reproduce: the held-out synthetic Canon frames of a
photographic run (``--synthetic``, e.g. runs/rdpd-light-photographs/data/canon-840-test) deblurred
as they are and with the measured disparity falloff added (crosstalk ``1 - k f^2`` in linear
light), gain by zone.

    python experiments/scripts/formation_across_field.py ../shared/data/canon-dp-real \
        --synthetic runs/rdpd-light-photographs/data/canon-840-test \
        --figure docs/figures/formation_edge_kernels.png
"""

from __future__ import annotations

import argparse
import glob
import os

import numpy as np
import torch

import dualpixel
from dualpixel.calibration.camera import MIN_TEXTURE, estimate_block_kernels, fit_blocks
from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.tone import linear_to_srgb_array, srgb_to_linear_array

ZONES = ((0.0, 0.35), (0.35, 0.7), (0.7, 1.01))
RADII = ((0.0, 2.0), (2.0, 4.5), (4.5, 8.0), (8.0, 12.1))
PATCH = 48


def field_map(height: int, width: int) -> np.ndarray:
    """Distance of every pixel from the frame's centre, a fraction of the half-diagonal."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    return np.hypot(x - (width - 1) / 2, y - (height - 1) / 2) / np.hypot((width - 1) / 2,
                                                                          (height - 1) / 2)


def dev_blocks(root: str, model: str) -> tuple[np.ndarray, list]:
    """Per textured block: radius, field, input MSE, output MSE, |ratio|, texture, and the fit's
    residual and the views' variance per pixel (linear light); and the frames."""
    params = load_camera("canon-840-linear").psf
    radii = np.arange(0.0, 12.01, 0.5)
    rows, frames = [], []
    for scene in sorted(glob.glob(os.path.join(root, "scene_*"))):
        left, right, combined, target = (read_rgb(os.path.join(scene, f"{name}.png"))
                                         for name in ("view0", "view1", "input", "target"))
        output = dualpixel.deblur(left, right, model=model, device="cpu")
        linear = [srgb_to_linear_array(v) for v in (left, right, target)]
        fit = fit_blocks(*linear, params, radii, patch=PATCH)
        fit_pixels = 2 * PATCH * PATCH * left.shape[-1]  # both views, every channel
        height, width = target.shape[:2]
        centre = np.array([(width - 1) / 2, (height - 1) / 2])
        for index in np.ndindex(fit.radius.shape[:2]):
            if fit.texture[index].min() <= MIN_TEXTURE:
                continue
            x, y = (int(v - PATCH / 2) for v in fit.centres[index])
            block = (slice(y, y + PATCH), slice(x, x + PATCH))
            field = np.linalg.norm(fit.centres[index] - centre) / np.linalg.norm(centre)
            rows.append((fit.radius[index][1], field,
                         float(((combined[block] - target[block]) ** 2).mean()),
                         float(((output[block] - target[block]) ** 2).mean()),
                         abs(fit.ratio[index][1]), float(fit.texture[index].min()),
                         float(fit.residual[index].sum() / fit_pixels),
                         float(fit.variance[index].sum() / fit_pixels)))
            frames.append((scene, tuple(fit.centres[index]), linear))
    return np.array(rows), frames


def print_dev(rows: np.ndarray) -> None:
    print(f"dev scenes, {len(rows)} textured blocks: gain (dB) by radius and field zone")
    for low, high in RADII:
        cells = []
        for near, far in ZONES:
            inside = ((rows[:, 0] >= low) & (rows[:, 0] < high) & (rows[:, 1] >= near)
                      & (rows[:, 1] < far))
            gain = (10 * np.log10(rows[inside, 2].sum() / rows[inside, 3].sum())
                    if inside.any() else float("nan"))
            cells.append(f"{gain:+.2f} (n={int(inside.sum())})")
        print(f"  r {low:4.1f}-{high:4.1f} px: " + " | ".join(cells))
    large = rows[rows[:, 0] >= 4.5]
    zones = [large[(large[:, 1] >= a) & (large[:, 1] < b)] for a, b in ZONES]
    for column, label in ((2, "input MSE"), (3, "output MSE"), (6, "fit residual / px"),
                          (7, "views' variance / px")):
        print(f"  r >= 4.5 px, {label} by zone, mean: " + " ".join(
            f"{z[:, column].mean():.2e}" for z in zones) + "; median: " + " ".join(
            f"{np.median(z[:, column]):.2e}" for z in zones))
    print("  disparity ratio (r >= 4.5 px), median by zone: " + " ".join(
        f"{np.median(large[(large[:, 1] >= a) & (large[:, 1] < b), 4]):.2f}" for a, b in ZONES))


def kernel_figure(rows: np.ndarray, frames: list, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # well-textured blocks whose fit is plausible (kernels of flat blocks are noise)
    blurred = [i for i in range(len(rows))
               if rows[i, 0] >= 5 and rows[i, 5] > 2 * MIN_TEXTURE and 0.3 < rows[i, 4] < 1.3]
    blurred.sort(key=lambda i: rows[i, 1])
    groups = (("centre", blurred[:6]), ("edge", blurred[-6:]))
    fig, axes = plt.subplots(4, 6, figsize=(12, 8.4))
    for g, (label, picks) in enumerate(groups):
        for j, i in enumerate(picks):
            scene, centre, (left, right, target) = frames[i]
            half = int(np.ceil(rows[i, 0] * 1.6)) + 2
            kernels = estimate_block_kernels(left, right, target, centre, PATCH, half)
            for k, (kernel, view) in enumerate(zip(kernels, "LR")):
                ax = axes[2 * g + k, j]
                ax.imshow(kernel, cmap="magma")
                ax.set_xticks([])
                ax.set_yticks([])
                ax.set_title(f"{label} {view}: {os.path.basename(scene)}\nf={rows[i, 1]:.2f} "
                             f"r={rows[i, 0]:.1f} a={rows[i, 4]:.2f}", fontsize=7)
    fig.suptitle("Estimated DP kernels of textured real Canon blocks blurred >= 5 px: nearest the "
                 "frame's centre (rows 1-2) and farthest from it (rows 3-4)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def synthetic_falloff(root: str, model: str, falloffs: list[float], count: int) -> None:
    names = sorted(os.listdir(os.path.join(root, "test_l", "source")))[:: max(1, 44 // count)]
    totals = {k: np.zeros((2, len(ZONES))) for k in falloffs}
    for name in names[:count]:
        left, right, combined, target = (
            read_rgb(os.path.join(root, part, name, "frame_0000.png"))
            for part in ("test_l/source", "test_r/source", "test_c/source", "test_c/target"))
        field = field_map(*target.shape[:2])
        zones = [(field >= a) & (field < b) for a, b in ZONES]
        light = [srgb_to_linear_array(v) for v in (left, right)]
        for k in falloffs:
            keep = (1 + (1 - k * field**2)[..., None]) / 2
            views = [linear_to_srgb_array(keep * a + (1 - keep) * b)
                     for a, b in (light, light[::-1])]
            output = dualpixel.deblur(*views, model=model, device="cpu")
            for z, zone in enumerate(zones):
                totals[k][:, z] += (((combined - target)[zone] ** 2).mean(),
                                    ((output - target)[zone] ** 2).mean())
    print(f"synthetic {os.path.basename(root)} ({count} frames): gain by field zone")
    for k, total in totals.items():
        print(f"  falloff k={k:g}: " + " ".join(f"{10 * np.log10(total[0, z] / total[1, z]):+.2f}"
                                             for z in range(len(ZONES))))


def shading_robustness(root: str, model: str, amplitude: float, count: int) -> None:
    """PSNR of held-out synthetic frames deblurred as they are and with DP shading added: the
    left view's light times ``sqrt(g)``, the right's over it, ``g`` a ramp from ``1 + amplitude``
    at the left edge to ``1 - amplitude`` at the right (the combined light nearly unchanged)."""
    names = sorted(os.listdir(os.path.join(root, "test_l", "source")))[:: max(1, 44 // count)]
    scores = {"as made": [], "shaded": []}
    for name in names[:count]:
        left, right, target = (read_rgb(os.path.join(root, part, name, "frame_0000.png"))
                               for part in ("test_l/source", "test_r/source", "test_c/target"))
        ramp = np.sqrt(1 + amplitude * np.linspace(1, -1, left.shape[1], dtype=np.float32))
        shaded = [linear_to_srgb_array(np.clip(srgb_to_linear_array(v) * g[None, :, None], 0, 1))
                  for v, g in ((left, ramp), (right, 1 / ramp))]
        for label, views in (("as made", (left, right)), ("shaded", shaded)):
            output = dualpixel.deblur(*views, model=model, device="cpu")
            scores[label].append(10 * np.log10(1 / ((output - target) ** 2).mean()))
    print(f"{os.path.basename(root)} ({count} frames), shading +-{amplitude:g}: " + ", ".join(
        f"{label} {np.mean(values):.2f} dB" for label, values in scores.items()))


def shading(root: str) -> None:
    """The left view's light over the right's in five column bands (sums in linear light: blur
    moves light locally, a band's sum keeps it): DP shading the views were not corrected for."""
    print(f"DP shading of {root}: left / right light by column band")
    for folder in sorted(glob.glob(os.path.join(root, "*", ""))):
        if not os.path.exists(os.path.join(folder, "left.png")):
            continue
        left, right = (srgb_to_linear_array(read_rgb(os.path.join(folder, f"{v}.png"))).mean(-1)
                       for v in ("left", "right"))
        bands = np.array_split(np.arange(left.shape[1]), 5)
        ratios = [left[:, b].sum() / max(right[:, b].sum(), 1e-9) for b in bands]
        name = os.path.basename(folder.rstrip("/"))
        print(f"  {name:26s} " + " ".join(f"{r:.3f}" for r in ratios))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("root")
    parser.add_argument("--model", default="rdpd-light")
    parser.add_argument("--figure", default=None)
    parser.add_argument("--synthetic", default=None)
    parser.add_argument("--falloffs", default="0,0.3,0.6")
    parser.add_argument("--count", type=int, default=8)
    parser.add_argument("--shading", default=None, help="a folder of NAME/left.png, right.png")
    parser.add_argument("--shading-test", default=None,
                        help="a written held-out set to deblur with DP shading added")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.shading:
        shading(args.shading)
    if args.shading_test:
        shading_robustness(args.shading_test, args.model, 0.15, args.count)
    rows, frames = dev_blocks(args.root, args.model)
    print_dev(rows)
    if args.figure:  # (the kernels are estimated in grey, least squares with a smoothness term)
        kernel_figure(rows, frames, args.figure)
    if args.synthetic:
        synthetic_falloff(args.synthetic, args.model,
                          [float(k) for k in args.falloffs.split(",")], args.count)


if __name__ == "__main__":
    main()
