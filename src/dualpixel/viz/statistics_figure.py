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

#: Per panel: the statistic, its title, and the bins' (low, high, width); the range grows to
#: hold every value of every dataset, so nothing is piled into the end bins.
_PANELS = (
    ("disparity", "disparity between the views (px, per 64-px block)", (-8.0, 8.0, 0.25)),
    ("blur", "blur: best Gaussian std target -> input (px, per block)", (-0.125, 2.0, 0.25)),
    ("noise", "noise std of the input (per image)", (0.0, 0.04, 0.00125)),
    ("gradient_fraction", "fraction of input pixels with |gradient| > 0.05", (0.0, 0.4, 0.0125)),
)


def _edges(values: list[np.ndarray], low: float, high: float, width: float) -> np.ndarray:
    """Bin edges of ``width`` from ``low`` to ``high``, widened in whole bins to hold all
    ``values``."""
    data = np.concatenate([v.ravel() for v in values]) if values else np.zeros(0)
    if data.size:
        low = low - width * np.ceil(max(0.0, low - float(data.min())) / width)
        high = high + width * np.ceil(max(0.0, float(data.max()) - high) / width)
    return low + width * np.arange(round((high - low) / width) + 1)


def render_statistics_figure(stats: list[DatasetStatistics], output: str | Path) -> Path:
    """One panel per statistic, each dataset as a normalised histogram with its median marked."""
    fig, axes = plt.subplots(1, len(_PANELS), figsize=(4.6 * len(_PANELS), 3.6),
                             constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (key, title, bins) in zip(axes, _PANELS):
        edges = _edges([getattr(item, key) for item in stats if getattr(item, key).size], *bins)
        for index, item in enumerate(stats):
            values = getattr(item, key)
            if values.size == 0:
                continue
            colour = colours[index % len(colours)]
            label = f"{item.name} ({item.size[1]}x{item.size[0]}, {item.frames} frames)"
            ax.hist(values, bins=edges, density=True, histtype="step", linewidth=1.6,
                    color=colour, label=label)
            ax.axvline(float(np.median(values)), color=colour, linestyle="--", linewidth=1)
        limits = {item.max_blur for item in stats if key == "blur" and item.blur.size
                  and float(item.blur.max()) >= item.max_blur}
        for limit in limits:  # blocks blurrier than the search reaches pile up here
            ax.axvline(limit, color="grey", linestyle=":", linewidth=1)
            ax.annotate(f"search limit {limit:g} px:\nblurrier blocks pile here", (limit, 1.0),
                        xycoords=("data", "axes fraction"), xytext=(-4, -4),
                        textcoords="offset points", ha="right", va="top", fontsize=7,
                        color="grey")
        ax.set_title(title, fontsize=9)
        ax.set_yticks([])
    axes[0].legend(fontsize=7, loc="upper left")
    save_figure(fig, output, dpi=110)
    return Path(output)
