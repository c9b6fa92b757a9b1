"""Issue #77 item 3: blocks at depth edges against the rest, on real and synthetic views.

A block that straddles two depths holds two blurs, which no single PSF explains, and our
layered compositing decides what its views show there. Real dev Canon scenes (840 px): a block
is at a depth edge where the target-calibrated fit's radius (green, linear light, the Canon
camera's shape) differs from a neighbour's by at least ``--jump`` px. Synthetic held-out frames
(``--synthetic``, a written set with its ``defocus`` maps): where the block's own CoC radii span
at least ``--jump`` px. Per kind of block and blur size: how many, the default model's gain over
the input and its output's squared error, and for the real blocks the share of the views'
variance the fit leaves.

    python experiments/scripts/formation_depth_edges.py ../shared/data/canon-dp-real \
        --synthetic runs/rdpd-light-photographs/data/canon-840-test
"""

from __future__ import annotations

import argparse
import glob
import os

import numpy as np
import torch

import dualpixel
from dualpixel.calibration.camera import MIN_TEXTURE, fit_blocks
from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.tone import srgb_to_linear_array

PATCH = 48
RADII = ((0.0, 2.0), (2.0, 4.5), (4.5, 12.1))


def neighbour_jump(radius: np.ndarray) -> np.ndarray:
    """Per block of a ``(rows, cols)`` radius map, the largest difference to a 4-neighbour."""
    padded = np.pad(radius, 1, mode="edge")
    centre = padded[1:-1, 1:-1]
    return np.max(np.stack([np.abs(centre - padded[:-2, 1:-1]), np.abs(centre - padded[2:, 1:-1]),
                            np.abs(centre - padded[1:-1, :-2]), np.abs(centre - padded[1:-1, 2:])]),
                  axis=0)


def real_blocks(root: str, model: str, jump: float) -> np.ndarray:
    """Rows (radius, at an edge, input MSE, output MSE, fit residual, views' variance, the
    published DPDNet output's MSE)."""
    params = load_camera("canon-840-linear").psf
    rows = []
    for scene in sorted(glob.glob(os.path.join(root, "scene_*"))):
        left, right, combined, target, published = (
            read_rgb(os.path.join(scene, f"{n}.png"))
            for n in ("view0", "view1", "input", "target", "dpdnet"))
        output = dualpixel.deblur(left, right, model=model, device="cpu")
        fit = fit_blocks(*(srgb_to_linear_array(v) for v in (left, right, target)), params,
                         np.arange(0.0, 12.01, 0.5), patch=PATCH)
        edges = neighbour_jump(fit.radius[..., 1]) >= jump
        for index in np.ndindex(fit.radius.shape[:2]):
            if fit.texture[index].min() <= MIN_TEXTURE:
                continue
            x, y = (int(v - PATCH / 2) for v in fit.centres[index])
            block = (slice(y, y + PATCH), slice(x, x + PATCH))
            rows.append((fit.radius[index][1], float(edges[index]),
                         float(((combined[block] - target[block]) ** 2).mean()),
                         float(((output[block] - target[block]) ** 2).mean()),
                         float(fit.residual[index].sum()), float(fit.variance[index].sum()),
                         float(((published[block] - target[block]) ** 2).mean())))
    return np.array(rows)


def synthetic_blocks(root: str, model: str, jump: float, count: int) -> np.ndarray:
    """Rows (median |CoC|, at an edge, input MSE, output MSE) of textured blocks."""
    names = sorted(os.listdir(os.path.join(root, "test_l", "source")))[:: max(1, 44 // count)]
    rows = []
    for name in names[:count]:
        left, right, combined, target = (
            read_rgb(os.path.join(root, part, name, "frame_0000.png"))
            for part in ("test_l/source", "test_r/source", "test_c/source", "test_c/target"))
        coc = np.abs(np.load(os.path.join(root, "test_c", "defocus", name, "frame_0000.npy")))
        output = dualpixel.deblur(left, right, model=model, device="cpu")
        height, width = target.shape[:2]
        for y in range(0, height - PATCH + 1, PATCH):
            for x in range(0, width - PATCH + 1, PATCH):
                block = (slice(y, y + PATCH), slice(x, x + PATCH))
                sharp = target[block].mean(-1)
                if np.abs(np.diff(sharp, axis=1)).mean() <= MIN_TEXTURE:
                    continue
                radii = coc[block]
                spread = float(np.percentile(radii, 95) - np.percentile(radii, 5))
                rows.append((float(np.median(radii)), float(spread >= jump),
                             float(((combined[block] - target[block]) ** 2).mean()),
                             float(((output[block] - target[block]) ** 2).mean())))
    return np.array(rows)


def report(label: str, rows: np.ndarray) -> None:
    print(label)
    for low, high in RADII:
        cells = []
        for edge in (0.0, 1.0):
            inside = (rows[:, 0] >= low) & (rows[:, 0] < high) & (rows[:, 1] == edge)
            if not inside.any():
                cells.append("-")
                continue
            part = rows[inside]
            gain = 10 * np.log10(part[:, 2].sum() / part[:, 3].sum())
            text = f"n={len(part)} gain {gain:+.2f} out {part[:, 3].mean():.2e}"
            if rows.shape[1] > 4:
                text += f" unexplained {part[:, 4].sum() / part[:, 5].sum():.3f}"
                dpdnet = 10 * np.log10(part[:, 2].sum() / part[:, 6].sum())
                text += f" (DPDNet gain {dpdnet:+.2f} out {part[:, 6].mean():.2e})"
            cells.append(text)
        print(f"  r {low:4.1f}-{high:4.1f} px   smooth: {cells[0]}   |   at depth edges: "
              f"{cells[1]}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("root")
    parser.add_argument("--model", default="rdpd-light")
    parser.add_argument("--jump", type=float, default=2.0)
    parser.add_argument("--synthetic", default=None)
    parser.add_argument("--count", type=int, default=8)
    args = parser.parse_args()
    torch.set_num_threads(2)
    report("dev Canon scenes (radius: the fit's, edges: a neighbour's radius differs)",
           real_blocks(args.root, args.model, args.jump))
    if args.synthetic:
        report(f"synthetic {os.path.basename(args.synthetic)} (radius: the CoC map's median, "
               "edges: its 5-95 % spread)",
               synthetic_blocks(args.synthetic, args.model, args.jump, args.count))


if __name__ == "__main__":
    main()
