"""Issue #77 item 3: how much of the real-to-synthetic gap at mild blur is the views' coding.

The dev Canon views at 840 px are frames of a GIF (a 256-colour palette per frame, error-diffusion
dither), the target and the published DPDNet output too; DPDNet ran on the original 16-bit views.
Held-out synthetic frames (a written set with its ``defocus`` maps) are scored per blur size as
written and after the same coding of every image (views, combined input, target), each with its
own palette (Pillow's median cut, Floyd-Steinberg dither), as the real frames were made.

    python experiments/scripts/formation_view_coding.py runs/coding/canon-840 --count 12
"""

from __future__ import annotations

import argparse
import os

import numpy as np
import torch
from PIL import Image

import dualpixel
from dualpixel.calibration.camera import MIN_TEXTURE
from dualpixel.io.images import read_rgb

PATCH = 48
RADII = ((0.0, 2.0), (2.0, 4.5), (4.5, 12.1))


def gif_frame(image: np.ndarray) -> np.ndarray:
    """An (H, W, 3) float image in [0, 1] as a GIF frame stores it: its own 256-colour palette,
    Floyd-Steinberg dither; returned as float in [0, 1]."""
    pil = Image.fromarray(np.clip(np.rint(image * 255), 0, 255).astype(np.uint8))
    coded = pil.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                         dither=Image.Dither.FLOYDSTEINBERG).convert("RGB")
    return np.asarray(coded, dtype=np.float32) / 255.0


def blocks(root: str, model: str, count: int, coding: str) -> np.ndarray:
    """Rows (median |CoC| px, input MSE, output MSE) of textured blocks, 8-bit scale."""
    names = sorted(os.listdir(os.path.join(root, "test_l", "source")))[:count]
    rows = []
    for name in names:
        images = [read_rgb(os.path.join(root, part, name, "frame_0000.png"))
                  for part in ("test_l/source", "test_r/source", "test_c/source", "test_c/target")]
        coded = [gif_frame(image) for image in images] if coding != "none" else images
        views = coded[:2] if coding in ("gif", "gif-views") else images[:2]
        output = dualpixel.deblur(*views, model=model, device="cpu")
        if coding == "gif-output":  # clean views, the output coded as DPDNet's was published
            output = gif_frame(output)
        # "gif-views": the coded input scored against the clean target
        combined, target = coded[2], (images if coding == "gif-views" else coded)[3]
        coc = np.abs(np.load(os.path.join(root, "test_c", "defocus", name, "frame_0000.npy")))
        height, width = target.shape[:2]
        for y in range(0, height - PATCH + 1, PATCH):
            for x in range(0, width - PATCH + 1, PATCH):
                block = (slice(y, y + PATCH), slice(x, x + PATCH))
                if np.abs(np.diff(target[block].mean(-1), axis=1)).mean() <= MIN_TEXTURE:
                    continue
                rows.append((float(np.median(coc[block])),
                             float(((combined[block] - target[block]) ** 2).mean()),
                             float(((output[block] - target[block]) ** 2).mean())))
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("synthetic", help="a written held-out set with defocus maps")
    parser.add_argument("--model", default="rdpd-light")
    parser.add_argument("--count", type=int, default=12)
    parser.add_argument("--codings", nargs="+", default=["none", "gif", "gif-views", "gif-output"],
                        help="none: as written; gif: every image coded (the real dev frames); "
                             "gif-views: coded input, clean target; gif-output: clean views, "
                             "the output, input and target coded (DPDNet's published frames)")
    args = parser.parse_args()
    torch.set_num_threads(2)
    for coding in args.codings:
        rows = blocks(args.synthetic, args.model, args.count, coding)
        cells = []
        for low, high in RADII:
            part = rows[(rows[:, 0] >= low) & (rows[:, 0] < high)]
            gain = 10 * np.log10(part[:, 1].sum() / part[:, 2].sum())
            cells.append(f"{low:.1f}-{high:.1f} px: {gain:+.2f} dB ({len(part)})")
        whole = 10 * np.log10(rows[:, 1].sum() / rows[:, 2].sum())
        print(f"{args.model} coding {coding:5s} " + "   ".join(cells) + f"   all: {whole:+.2f}")


if __name__ == "__main__":
    main()
