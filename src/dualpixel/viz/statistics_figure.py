"""Histograms of dataset statistics side by side (see :mod:`dualpixel.data.statistics`)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dualpixel.data.statistics import DatasetStatistics
from dualpixel.viz.figures import save_figure

__all__ = ["render_statistics_figure"]

_PANELS = (
    ("disparity", "disparity between the views (px, per 64-px block)", np.linspace(-8, 8, 65)),
    ("blur", "blur: best Gaussian std target -> input (px, per block)", None),
    ("noise", "noise std of the input (per image)", np.linspace(0, 0.04, 33)),
    ("gradient_fraction", "fraction of input pixels with |gradient| > 0.05",
     np.linspace(0, 0.4, 33)),
)


def render_statistics_figure(stats: list[DatasetStatistics], output: str | Path) -> Path:
    """One panel per statistic, each dataset as a normalised histogram with its median marked."""
    fig, axes = plt.subplots(1, len(_PANELS), figsize=(4.6 * len(_PANELS), 3.6),
                             constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (key, title, bins) in zip(axes, _PANELS):
        for index, item in enumerate(stats):
            values = getattr(item, key)
            if values.size == 0:
                continue
            edges = bins if bins is not None else np.arange(-0.125, item.max_blur + 0.25, 0.25)
            colour = colours[index % len(colours)]
            label = f"{item.name} ({item.size[1]}x{item.size[0]}, {item.frames} frames)"
            ax.hist(np.clip(values, edges[0], edges[-1]), bins=edges, density=True,
                    histtype="step", linewidth=1.6, color=colour, label=label)
            ax.axvline(float(np.median(values)), color=colour, linestyle="--", linewidth=1)
        ax.set_title(title, fontsize=9)
        ax.set_yticks([])
    axes[0].legend(fontsize=7, loc="upper left")
    save_figure(fig, output, dpi=110)
    return Path(output)
