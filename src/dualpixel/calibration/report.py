"""The PSF-fit report: per-PSF table, averages and a figure like the supplement's Fig. S2."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import torch

from dualpixel.calibration.psf_fit import PSFFit
from dualpixel.io.atomic import atomic_path
from dualpixel.optics.camera import DPCamera
from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.viz.figures import save_figure

__all__ = ["camera_from_fits", "model_kernels", "summarise_fits", "write_fit_report"]


def model_kernels(fit: PSFFit, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Our fitted kernel and Punnappurath's for the fit's view, each summing to 1."""
    ours = dp_psf(fit.radius, PSFParams(fit.n, fit.alpha, fit.beta, fit.kappa), size=size,
                  dtype=torch.float64)
    theirs = dp_psf(fit.punnappurath_radius, model="punnappurath", size=size, dtype=torch.float64)
    pick = (lambda k: k.left) if fit.view == "left" else (lambda k: k.right)
    return tuple(2 * pick(k).numpy() for k in (ours, theirs))


def summarise_fits(fits: list[PSFFit]) -> dict:
    ours = np.array([f.correlation for f in fits])
    theirs = np.array([f.punnappurath_correlation for f in fits])
    best_case = np.array([f.punnappurath_best_correlation for f in fits])
    return {
        "pairs": len({f.index for f in fits}),
        "kernels": len(fits),
        "mean_correlation_ours": float(ours.mean()),
        "mean_correlation_punnappurath": float(theirs.mean()),
        "mean_correlation_punnappurath_best_case": float(best_case.mean()),
        "ours_better_count": int((ours > theirs).sum()),
        "most_common_parameters": _mode(fits),
    }


def _mode(fits: list[PSFFit]) -> dict:
    keys = [(f.n, f.alpha, f.beta, f.kappa) for f in fits]
    values, counts = np.unique(np.array(keys), axis=0, return_counts=True)
    n, alpha, beta, kappa = values[int(np.argmax(counts))]
    return {"n": n, "alpha": alpha, "beta": beta, "kappa": kappa, "count": int(counts.max())}


def _figure(fits: list[PSFFit], measured: dict[str, np.ndarray], path: Path, count: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    indices = sorted({f.index for f in fits})
    positions = np.linspace(0, len(indices) - 1, min(count, len(indices)))
    chosen = [indices[round(k)] for k in positions]
    size = measured["left"].shape[-1]
    fig, axes = plt.subplots(len(chosen), 6, figsize=(12, 2.2 * len(chosen)), squeeze=False)
    for row, index in enumerate(chosen):
        for half, view in enumerate(("left", "right")):
            fit = next(f for f in fits if f.index == index and f.view == view)
            ours, theirs = model_kernels(fit, size)
            panels = [("measured", measured[view][index]),
                      (f"Punnappurath\nX={fit.punnappurath_correlation:.3f}", theirs),
                      (f"ours n={fit.n:g} a={fit.alpha:g} b={fit.beta:g}\nX={fit.correlation:.3f}",
                       ours)]
            for col, (title, kernel) in enumerate(panels):
                ax = axes[row, 3 * half + col]
                ax.imshow(kernel, cmap="inferno")
                ax.set_title(f"#{index} {view} {title}", fontsize=7)
                ax.axis("off")
    fig.suptitle("Measured DP PSFs vs Punnappurath et al. and our fitted model (cf. Fig. S2)")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def write_fit_report(fits: list[PSFFit], measured: dict[str, np.ndarray], output: str | Path,
                     *, figure_rows: int = 4, meta: dict | None = None) -> dict:
    """Write ``fits.csv``, ``summary.json``, ``summary.md`` and ``figure.png`` into ``output``."""
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(fits[0].as_dict()))
    writer.writeheader()
    for fit in fits:
        writer.writerow(fit.as_dict())
    summary = {**summarise_fits(fits), **(meta or {})}
    markdown = (
        "| model | mean 2-D correlation | better on |\n|---|---|---|\n"
        f"| ours (Butterworth, Eq. 2-4) | {summary['mean_correlation_ours']:.4f} | "
        f"{summary['ours_better_count']} of {summary['kernels']} |\n"
        f"| Punnappurath et al. 2020 | {summary['mean_correlation_punnappurath']:.4f} | "
        f"{summary['kernels'] - summary['ours_better_count']} of {summary['kernels']} |\n"
        f"| Punnappurath, best case (radius chosen by correlation) | "
        f"{summary['mean_correlation_punnappurath_best_case']:.4f} | – |\n"
    )
    for name, text in (("fits.csv", buffer.getvalue()), ("summary.json",
                       json.dumps(summary, indent=2)), ("summary.md", markdown)):
        with atomic_path(output / name) as tmp:
            tmp.write_text(text)
    _figure(fits, measured, output / "figure.png", figure_rows)
    return summary


def camera_from_fits(fits: list[PSFFit], *, name: str, width: int,
                     light: str = "linear") -> DPCamera:
    """A camera file (:class:`~dualpixel.calibration.camera.DPCamera`) from measured DP PSFs:
    the most common fitted shape of Eq. 2-4 (:func:`summarise_fits`), the paper's disparity in
    every channel (the PSFs of one colour channel say nothing of the others), the fitted CoC
    radii as its blur sizes (px at ``width``, the width of the frames the PSFs were measured
    in) and ``light`` ("linear" for PSFs measured on raw data)."""
    mode = _mode(fits)
    radii = np.array([f.radius for f in fits])
    percentiles = {f"p{p}": round(float(np.percentile(radii, p)), 2) for p in (10, 25, 50, 75, 90)}
    return DPCamera(name=name, width=width, disparity_ratio=(1.0, 1.0, 1.0),
                    psf=PSFParams(*(float(mode[k]) for k in ("n", "alpha", "beta", "kappa"))),
                    coc_percentiles=percentiles, blocks=len(fits), light=light)
