"""The formation residual of issue #77 item 2, its blur sizes from the whitened identity at the
camera's own disparity ratios (:mod:`dualpixel.calibration.target_free`).

The first try (``formation_residual.py``) took each block's radius from the plain identity with
the paper's kernels; the sharp target then explained the dev views worse than the blurred input.
The views alone fix the product of ratio and radius, not the blur they share (the guide's
"A camera from its views alone"), so here each block's radius and side come from the whitened
identity *at the camera file's ratios* (``canon-840-linear``: measured with targets), which ties
the disparity to the camera's own blur. Then every candidate image ``X`` (the target, the
input, a model's output) is blurred by the camera's left and right kernels at that radius, with
one gain per block and channel, against both views; the residual over the views' own detail, over
informative blocks (linear light, per channel). Lower is better; a measure only if the target
scores below the input on the dev scenes.

    python experiments/scripts/formation_residual_camera.py [OUT] [MODELS...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np

import dualpixel
from dualpixel.calibration.camera import view_kernels
from dualpixel.calibration.target_free import RATIO_GRID, blocks_at_ratios, view_energies
from dualpixel.data.statistics import block_sums
from dualpixel.io.images import read_rgb
from dualpixel.optics.camera import load_camera
from dualpixel.optics.tone import srgb_to_linear_array

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"
PATCH = 48
RADII = np.arange(0.25, 12.01, 0.25)


def block_blur(left: np.ndarray, right: np.ndarray, camera):
    """Per block: radius (px), side (+1 / -1) and whether it is informative, at the camera's
    ratios; and the blocks' corner (margin)."""
    energies = view_energies(left, right, camera.psf, RADII, RATIO_GRID, patch=PATCH)
    fit = blocks_at_ratios([energies], camera.disparity_ratio)
    margin = int(energies.centres[0, 0, 0] - PATCH / 2)
    return fit.radius[0], fit.side[0], fit.informative[0], margin


def residual(left, right, candidate, camera, radius, side, informative, margin,
             smooth: float = 0.0) -> float:
    """``smooth``: a Gaussian (px) applied to the views and the blurred candidate alike (the
    identity holds under any common filter; the views' noise falls faster than their blur)."""
    if smooth > 0:
        left, right = (cv2.GaussianBlur(v, (0, 0), smooth) for v in (left, right))
        candidate = cv2.GaussianBlur(candidate, (0, 0), smooth)
    rows, cols = radius.shape
    inner = (slice(margin, margin + rows * PATCH), slice(margin, margin + cols * PATCH))
    error = np.zeros((rows, cols, 3))
    views = np.stack([left[inner], right[inner]])  # (2, h, w, 3)
    for r in np.unique(radius[informative]):
        for s in (1, -1):
            chosen = informative & (radius == r) & (side == s)
            if not chosen.any():
                continue
            k_left, k_right = view_kernels(r, camera.psf)
            if s < 0:
                k_left, k_right = k_right, k_left
            blurred = []
            for k_own, k_other in ((k_left, k_right), (k_right, k_left)):
                own, other = (cv2.filter2D(candidate, -1, k, borderType=cv2.BORDER_REFLECT)[inner]
                              for k in (k_own, k_other))
                a = np.asarray(camera.disparity_ratio, np.float32)
                blurred.append((1 + a) / 2 * own + (1 - a) / 2 * other)
            blurred = np.stack(blurred)
            cross = block_sums((blurred * views).sum(0), PATCH, np.float64)
            power = block_sums((blurred**2).sum(0), PATCH, np.float64)
            own = block_sums((views**2).sum(0), PATCH, np.float64)
            fitted = own - cross**2 / np.maximum(power, 1e-12)
            error[chosen] = fitted[chosen]
    mean = views.mean(axis=(1, 2), keepdims=True)
    detail = block_sums(((views - mean) ** 2).sum(0), PATCH, np.float64)
    return float(error[informative].sum() / max(detail[informative].sum(), 1e-12))


def main(out: Path, models: list[str]) -> None:
    camera = load_camera("canon-840-linear")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "residuals.json"
    results = json.loads(path.read_text()) if path.is_file() else {}
    for scene in sorted((SHARED / "canon-dp-real").glob("scene_*")):
        row = results.get(scene.name, {})
        left, right = (read_rgb(scene / f"{v}.png") for v in ("view0", "view1"))
        linear = [srgb_to_linear_array(v).astype(np.float32) for v in (left, right)]
        radius, side, informative, margin = block_blur(*linear, camera)
        candidates = {k: read_rgb(scene / f"{k}.png") for k in ("target", "input", "dpdnet")}
        for model in models:
            if model not in row:
                candidates[model] = dualpixel.deblur(left, right, model=model, device="cpu")
        for name, image in candidates.items():
            row[name] = residual(*linear, srgb_to_linear_array(np.asarray(image, np.float32))
                                 .astype(np.float32), camera, radius, side, informative, margin)
        row["blocks"] = int(informative.sum())
        results[scene.name] = row
        path.write_text(json.dumps(results, indent=1))
        print(scene.name, {k: round(v, 4) for k, v in row.items()}, flush=True)
    keys = [k for k in next(iter(results.values())) if k != "blocks"]
    print("mean", {k: round(float(np.mean([r[k] for r in results.values()])), 4) for k in keys})


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "runs" / "formation-camera",
         sys.argv[2:])
