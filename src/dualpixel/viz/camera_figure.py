"""The figure of ``dualpixel calibrate camera``: what the camera model rests on."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualpixel.viz.figures import save_figure

__all__ = ["model_disparity", "render_camera_figure"]

CHANNELS = (("red", "tab:red"), ("green", "tab:green"), ("blue", "tab:blue"))


def model_disparity(radii: np.ndarray, params) -> np.ndarray:
    """Centroid distance (px) between the right and left kernels of our model (a = 1) per
    CoC radius (px, >= 0)."""
    from dualpixel.optics.psf import dp_psf

    out = []
    for radius in radii:
        kernels = dp_psf(float(radius), params)
        x = np.arange(kernels.left.shape[-1]) - kernels.left.shape[-1] // 2
        left, right = (2.0 * k.numpy().sum(axis=0) for k in (kernels.left, kernels.right))
        out.append(float((right * x).sum() - (left * x).sum()))
    return np.asarray(out)


def render_camera_figure(calibration, path: str | Path, *, kernels_shown: int = 3) -> Path:
    """Left: disparity against blur per channel (blocks, the camera's lines and the paper's
    model, a = 1). Right: kernels estimated from the strongest-blurred blocks beside the fitted
    model's (green channel), from the frames the calibration fitted (misaligned ones left out)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dualpixel.calibration.camera import estimate_block_kernels
    from dualpixel.optics.psf import dp_psf

    camera = calibration.camera
    radii = np.linspace(0.0, max(float(max(f.radius.max() for f in calibration.fits)), 1.0), 40)
    base = model_disparity(radii, camera.psf)
    fig = plt.figure(figsize=(13, 4.6))
    axis = fig.add_subplot(1, 2, 1)
    for c, (label, colour) in enumerate(CHANNELS):
        points_r, points_d = [], []
        for fit, usable in zip(calibration.fits, calibration.usable):
            r, a = fit.radius[..., c][usable], fit.ratio[..., c][usable]
            sign = np.sign(fit.ratio[..., 1][usable])
            points_r.append(r)
            points_d.append(a * sign * np.interp(r, radii, base))
        axis.scatter(np.concatenate(points_r) + (c - 1) * 0.06, np.concatenate(points_d), s=5,
                     alpha=0.25, color=colour)
        axis.plot(radii, camera.disparity_ratio[c] * base, color=colour,
                  label=f"{label}: {camera.disparity_ratio[c]:.2f} x model")
    axis.plot(radii, base, "k--", label="paper's model (training data before)")
    axis.set_xlabel("CoC radius r (px)")
    axis.set_ylabel("DP disparity (px, right minus left centroid)")
    axis.set_title(f"{camera.name}: disparity against blur ({camera.blocks} blocks)")
    axis.legend(fontsize=8)
    # kernels of the blurriest usable blocks (green)
    candidates = []
    for index, (fit, usable) in enumerate(zip(calibration.fits, calibration.usable)):
        for row, col in zip(*np.nonzero(usable)):
            candidates.append((float(fit.radius[row, col, 1]), index, row, col))
    candidates.sort(reverse=True)
    chosen = candidates[:: max(1, len(candidates) // (4 * kernels_shown))][:kernels_shown]
    for k, (radius, index, row, col) in enumerate(chosen):
        fit = calibration.fits[index]
        _, left, right, target = calibration.frames[index]
        half = int(np.ceil(radius * 1.4)) + 2
        patch = round(fit.centres[0, 1, 0] - fit.centres[0, 0, 0])
        estimated = estimate_block_kernels(left[..., 1:2], right[..., 1:2], target[..., 1:2],
                                           tuple(fit.centres[row, col]), patch, half)
        model = dp_psf(radius, camera.psf, size=2 * half + 1)
        ratio = fit.ratio[row, col, 1]
        a = abs(ratio)
        ml, mr = (2 * v.numpy() for v in (model.left, model.right))
        if ratio < 0:
            ml, mr = mr, ml
        ml, mr = (1 + a) / 2 * ml + (1 - a) / 2 * mr, (1 + a) / 2 * mr + (1 - a) / 2 * ml
        for j, (image, title) in enumerate(((estimated[0], "estimated L"),
                                            (estimated[1], "estimated R"),
                                            (ml, "model L"), (mr, "model R"))):
            sub = fig.add_subplot(kernels_shown, 8, k * 8 + 5 + j)
            sub.imshow(image, cmap="magma")
            sub.set_xticks([]), sub.set_yticks([])
            if k == 0:
                sub.set_title(title, fontsize=8)
            if j == 0:
                sub.set_ylabel(f"r={radius:.1f}", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
