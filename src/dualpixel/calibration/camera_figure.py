"""The figures of ``dualpixel calibrate camera``: what the camera model rests on."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualpixel.viz.figures import save_figure

__all__ = ["model_disparity", "render_camera_figure", "render_views_figure"]

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
    usable_radii = np.concatenate([f.radius[u].ravel() for f, u in zip(calibration.fits,
                                                                        calibration.usable)])
    # the axes hold 99.5 % of the blocks: one outlier does not squeeze the rest into a corner
    reach = float(np.percentile(usable_radii, 99.5)) if usable_radii.size else 1.0
    radii = np.linspace(0.0, max(reach * 1.05, 1.0), 40)
    base = model_disparity(radii, camera.psf)
    every = np.linspace(0.0, max(float(usable_radii.max(initial=1.0)), 1.0), 80)
    every_base = model_disparity(every, camera.psf)  # the points' own disparities, all of them
    fig = plt.figure(figsize=(13, 4.6))
    axis = fig.add_subplot(1, 2, 1)
    shown_r: list[np.ndarray] = []
    shown_d: list[np.ndarray] = []
    for c, (label, colour) in enumerate(CHANNELS):
        points_r, points_d = [], []
        for fit, usable in zip(calibration.fits, calibration.usable):
            r, a = fit.radius[..., c][usable], fit.ratio[..., c][usable]
            sign = np.sign(fit.ratio[..., 1][usable])
            points_r.append(r)
            points_d.append(a * sign * np.interp(r, every, every_base))
        axis.scatter(np.concatenate(points_r) + (c - 1) * 0.06, np.concatenate(points_d), s=5,
                     alpha=0.25, color=colour)
        shown_r.append(np.concatenate(points_r))
        shown_d.append(np.concatenate(points_d))
        axis.plot(radii, camera.disparity_ratio[c] * base, color=colour,
                  label=f"{label}: {camera.disparity_ratio[c]:.2f} x model")
    axis.plot(radii, base, "k--", label="paper's model (training data before)")
    disparities = np.concatenate(shown_d) if shown_d else np.zeros(0)
    if disparities.size:
        low, high = np.percentile(disparities, [0.5, 99.0])
        span = max(high - low, 1e-3)
        bottom = min(low, 0.0) - 0.05 * span
        top = max(high, float(base.max())) + 0.1 * span
        axis.set_ylim(bottom, top)
        beyond_r = np.concatenate(shown_r) > radii[-1] + 0.2  # each point counted once
        hidden = int(((disparities < bottom) | (disparities > top) | beyond_r).sum())
        if hidden:
            axis.text(0.99, 0.02, f"{hidden} outlying points beyond the axes", fontsize=7,
                      ha="right", transform=axis.transAxes)
    axis.set_xlim(-0.2, radii[-1] + 0.2)
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


def render_views_figure(calibration, pairs, path: str | Path, *, shown: int = 4) -> Path:
    """The figure of a calibration from views alone: per pair (the first ``shown``), the views'
    mean beside its blur map, each informative block's CoC radius signed by its side of the
    focal plane (blocks that tell nothing left blank)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fit = calibration.fit
    rows = min(shown, len(pairs))
    reach = max(float(np.max([r[m].max(initial=0.0) for r, m in zip(fit.radius,
                                                                   fit.informative)])), 1.0)
    height, width = np.asarray(pairs[0][1]).shape[:2]
    fig, axes = plt.subplots(rows, 2, figsize=(9.0, 4.2 * rows * height / width + 0.6),
                             squeeze=False, gridspec_kw={"wspace": 0.04, "hspace": 0.18})
    for row, (name, left, right, _) in enumerate(pairs[:rows]):
        combined = np.clip((np.asarray(left) + np.asarray(right)) / 2, 0.0, 1.0)
        axes[row, 0].imshow(combined[..., 0] if combined.shape[-1] == 1 else combined,
                            cmap="gray", vmin=0.0, vmax=1.0)
        axes[row, 0].set_title(Path(name).parent.name or Path(name).name, fontsize=9)
        signed = np.where(fit.informative[row], fit.side[row] * fit.radius[row], np.nan)
        centres = calibration.centres[row]
        step = float(centres[0, 1, 0] - centres[0, 0, 0]) if centres.shape[1] > 1 else 1.0
        extent = (centres[0, 0, 0] - step / 2, centres[0, -1, 0] + step / 2,
                  centres[-1, 0, 1] + step / 2, centres[0, 0, 1] - step / 2)
        image = axes[row, 1].imshow(signed, cmap="coolwarm", vmin=-reach, vmax=reach,
                                    extent=extent)
        axes[row, 1].set_xlim(0, combined.shape[1])
        axes[row, 1].set_ylim(combined.shape[0], 0)
        axes[row, 1].set_title("CoC radius from the views (px; sign: side of focus)",
                               fontsize=9)
        fig.colorbar(image, ax=axes[row, 1], fraction=0.035, pad=0.02)
        for axis in axes[row]:
            axis.set_xticks([])
            axis.set_yticks([])
    ratios = " / ".join(f"{v:.2f}" for v in calibration.camera.disparity_ratio)
    fig.suptitle(f"{calibration.camera.name}: disparity ratio {ratios} (R / G / B), light "
                 f"{calibration.camera.light}, {calibration.camera.blocks} informative blocks",
                 fontsize=10)
    return save_figure(fig, path)
