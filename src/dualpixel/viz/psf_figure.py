"""A figure like the paper's Fig. 5: combined, left and right DP PSFs, Punnappurath vs ours."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dualpixel.optics.psf import DPKernels, PSFParams, dp_psf, kernel_size
from dualpixel.viz.figures import save_figure

__all__ = ["psf_figure_kernels", "render_psf_figure"]


def psf_figure_kernels(
    radii: Sequence[float], params: PSFParams
) -> dict[str, DPKernels]:
    """Kernels of both models for the figure, all at one size so they compare pixel for pixel."""
    size = kernel_size(max(abs(r) for r in radii), "ours", params.kappa)
    return {
        "ours": dp_psf(list(radii), params, size=size),
        "punnappurath": dp_psf(list(radii), params, model="punnappurath", size=size),
    }


def render_psf_figure(
    path: str | Path, radii: Sequence[float], params: PSFParams
) -> dict[str, DPKernels]:
    """Write the PNG figure to ``path`` (atomically) and return the kernels shown."""
    kernels = psf_figure_kernels(radii, params)
    columns = [
        (model, view)
        for model in ("punnappurath", "ours")
        for view in ("combined", "left", "right")
    ]
    titles = {"punnappurath": "Punnappurath et al.", "ours": "ours (Butterworth)"}
    fig, axes = plt.subplots(
        len(radii), len(columns), figsize=(2.0 * len(columns) + 0.8, 2.0 * len(radii)),
        squeeze=False, constrained_layout=True,
    )
    for row, radius in enumerate(radii):
        images = {
            (model, view): np.asarray(getattr(kernels[model], view)[row].cpu())
            for model, view in columns
        }
        vmax = max(float(img.max()) for img in images.values())
        for col, key in enumerate(columns):
            ax = axes[row, col]
            shown = ax.imshow(images[key], cmap="inferno", vmin=0.0, vmax=vmax)
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(f"{titles[key[0]]}\n{key[1]}", fontsize=9)
            if col == 0:
                where = "behind focus" if radius > 0 else "in front" if radius < 0 else "in focus"
                ax.set_ylabel(f"r = {radius:+g} px\n({where})", fontsize=9)
        fig.colorbar(shown, ax=axes[row, :].tolist(), shrink=0.9, label="weight")
    fig.suptitle(
        f"Dual-pixel PSFs (n={params.n:g}, alpha={params.alpha:g}, beta={params.beta:g}, "
        f"kappa={params.kappa:g}); each view sums to 1/2",
        fontsize=10,
    )
    save_figure(fig, path, dpi=110)
    return kernels


def save_psf_kernels(path: str | Path, kernels: dict[str, DPKernels], radii: Sequence[float],
                     params: PSFParams) -> Path:
    """Write the figure's kernels as ``.npz`` (``left``, ``right``, ``combined`` (N, S, S) of ours,
    ``punnappurath_*`` of theirs, ``radii``, ``params`` = n, alpha, beta, kappa), atomically."""
    from dualpixel.io.atomic import atomic_path

    ours, theirs = kernels["ours"].numpy(), kernels["punnappurath"].numpy()
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        np.savez(handle, left=ours[0], right=ours[1], combined=ours[2], radii=np.asarray(radii),
                 punnappurath_left=theirs[0], punnappurath_right=theirs[1],
                 punnappurath_combined=theirs[2],
                 params=np.asarray([params.n, params.alpha, params.beta, params.kappa]))
    return Path(path)
