"""Issue #77: what deblurring at twice the resolution buys, on our own formation.

The published DPDNet's 840-px dev frames are its full-resolution output halved (computed from the
original 16-bit views); the default deblurs the 840-px views themselves. This script measures the
two routes for the default on synthetic frames whose truth is known: each photograph of
``--photos`` (at least ``--min-width`` wide, cropped to multiples of 32) gets a smooth random
depth map (1-15 m) and is rendered by our formation (``--camera``, noise, 8-bit views); then

- ``full, halved``: the default deblurs the full-resolution views, the output is area-halved;
- ``halved``: the default deblurs the area-halved views;

both scored against the area-halved target, per textured ``--tile``-px tile (PSNR gain over the
halved views' mean), by the tile's median CoC radius at half resolution.

    python experiments/scripts/resolution_route.py [--photos ../shared/data/photographs/validation]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import torch

import dualpixel
from dualpixel.io.images import image_size, read_rgb

BINS = ((0.0, 2.0), (2.0, 4.5), (4.5, 9.0), (9.0, 40.0))
ROUTES = ("full, halved", "halved")


def halved(image: np.ndarray) -> np.ndarray:
    """``(H, W, ...)`` area-averaged to ``(H // 2, W // 2, ...)``."""
    return cv2.resize(image, (image.shape[1] // 2, image.shape[0] // 2),
                      interpolation=cv2.INTER_AREA)


def smooth_depth(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A smooth random depth map (m), about 1-15 m: the exponential of a bicubic 6x9 field."""
    field = cv2.resize(rng.standard_normal((6, 9)), (width, height),
                       interpolation=cv2.INTER_CUBIC)
    return np.exp(1.0 + 0.9 * field).astype(np.float32)


def tile_gains(output: np.ndarray, blurred: np.ndarray, target: np.ndarray, radius: np.ndarray,
               tile: int) -> list[tuple[float, float]]:
    """``(radius, gain dB)`` per textured tile (mean absolute horizontal step of the target's
    grey >= 0.01)."""
    rows = []
    for y in range(0, target.shape[0] - tile + 1, tile):
        for x in range(0, target.shape[1] - tile + 1, tile):
            sharp = target[y : y + tile, x : x + tile]
            if np.abs(np.diff(sharp.mean(-1), axis=1)).mean() < 0.01:
                continue
            before = ((blurred[y : y + tile, x : x + tile] - sharp) ** 2).mean()
            after = ((output[y : y + tile, x : x + tile] - sharp) ** 2).mean()
            rows.append((float(np.median(radius[y : y + tile, x : x + tile])),
                         10 * np.log10(before / after)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=Path,
                        default=Path("../shared/data/photographs/validation"))
    parser.add_argument("--min-width", type=int, default=900)
    parser.add_argument("--count", type=int, default=16)
    parser.add_argument("--camera", default="canon-840-linear")
    parser.add_argument("--tile", type=int, default=32)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    photos = [p for p in sorted(args.photos.glob("*.jpg"))
              if image_size(p)[1] >= args.min_width and min(image_size(p)) >= 512][: args.count]
    tiles = {route: [] for route in ROUTES}
    whole = {route: [] for route in ROUTES}
    for number, photo in enumerate(photos):
        rgb = read_rgb(photo)
        height, width = rgb.shape[0] // 32 * 32, rgb.shape[1] // 32 * 32
        rgb = rgb[:height, :width]
        frame = dualpixel.synthesize(rgb, smooth_depth(rng, height, width), camera=args.camera,
                                     seed=number)
        left, right, target = (np.round(np.clip(frame[k], 0, 1) * 255) / 255
                               for k in ("left", "right", "target"))
        sharp, blurred = halved(target), halved((left + right) / 2)
        radius = halved(np.abs(frame["defocus"]).astype(np.float32)) / 2
        outputs = {"full, halved": halved(dualpixel.deblur(left, right, device="cpu")),
                   "halved": dualpixel.deblur(halved(left), halved(right), device="cpu")}
        for route, output in outputs.items():
            whole[route].append(10 * np.log10(((blurred - sharp) ** 2).mean()
                                              / ((output - sharp) ** 2).mean()))
            tiles[route] += tile_gains(output, blurred, sharp, radius, args.tile)
        print(f"{photo.name} {width}x{height}: "
              + ", ".join(f"{route} {whole[route][-1]:+.2f}" for route in ROUTES), flush=True)
    print(f"\n{len(photos)} frames, camera {args.camera}; PSNR gain over the halved views' mean, "
          "dB\n")
    print("| half-resolution blur | tiles | " + " | ".join(ROUTES) + " |")
    print("|---|---|" + "---|" * len(ROUTES))
    for low, high in BINS:
        gains = {route: [g for r, g in tiles[route] if low <= r < high] for route in ROUTES}
        if gains[ROUTES[0]]:
            print(f"| {low:g}-{high:g} px | {len(gains[ROUTES[0]])} | "
                  + " | ".join(f"{np.mean(gains[route]):+.2f}" for route in ROUTES) + " |")
    print("| whole frames | | " + " | ".join(f"{np.mean(whole[route]):+.2f}" for route in ROUTES)
          + " |")


if __name__ == "__main__":
    main()
