"""PSNR and share of the error by blur size (see :mod:`dualpixel.evaluation.blur_breakdown`)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dualpixel.evaluation.blur_breakdown import BlurBreakdown
from dualpixel.viz.figures import save_figure

__all__ = ["render_blur_breakdown"]


def render_blur_breakdown(breakdown: BlurBreakdown, output: str | Path) -> Path:
    """Two panels over the |CoC| bins: each method's PSNR (bars) with the pixels per bin, and
    each method's share of its total squared error."""
    rows = breakdown.table()
    methods = list(breakdown.squared_error)
    x = np.arange(len(rows))
    width = 0.8 / max(len(methods), 1)
    fig, (psnr_ax, share_ax) = plt.subplots(1, 2, figsize=(11, 3.8), constrained_layout=True)
    for index, method in enumerate(methods):
        offset = (index - (len(methods) - 1) / 2) * width
        psnr = [np.nan if r["psnr"][method] is None else r["psnr"][method] for r in rows]
        share = [100 * r["error_share"][method] for r in rows]
        psnr_ax.bar(x + offset, psnr, width, label=method)
        share_ax.bar(x + offset, share, width, label=method)
    labels = [f"{r['bin']}\n{100 * r['pixel_fraction']:.0f} % px" for r in rows]
    for ax, title in ((psnr_ax, "PSNR (dB, pooled per bin)"),
                      (share_ax, "share of the method's squared error (%)")):
        ax.set_xticks(x, labels, fontsize=7)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("true |CoC| radius", fontsize=8)
    finite = [v for r in rows for v in r["psnr"].values() if v is not None]
    if finite:
        psnr_ax.set_ylim(max(min(finite) - 3, 0), max(finite) + 2)
    psnr_ax.legend(fontsize=7)
    save_figure(fig, output, dpi=110)
    return Path(output)
