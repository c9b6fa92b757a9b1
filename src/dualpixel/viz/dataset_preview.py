"""A contact sheet of a synthetic DP dataset: target, left, right, combined and defocus map."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dualpixel.errors import InputFileError
from dualpixel.io.dpdd import read_manifest
from dualpixel.io.images import load_npy, read_rgb
from dualpixel.viz.figures import save_figure

__all__ = ["render_dataset_preview"]


def render_dataset_preview(dataset: str | Path, output: str | Path, *, rows: int = 5) -> Path:
    """Write a PNG with one row per sequence (its first frame): the sharp target, the left and
    right views, the combined blurred image and the signed defocus map (colour bar in px)."""
    root = Path(dataset)
    manifest = root / "manifest.jsonl"
    if not manifest.is_file():
        raise InputFileError(manifest, "not found: is this a dataset written by `dualpixel synth`?")
    records: dict[int, dict] = {}
    for record in read_manifest(manifest).values():
        records.setdefault(record["sequence"], record)
    chosen = [records[k] for k in sorted(records)[:rows]]
    if not chosen:
        raise InputFileError(manifest, "lists no finished frame")
    columns = ("target", "left", "right", "combined", "defocus")
    fig, axes = plt.subplots(len(chosen), len(columns), squeeze=False,
                             figsize=(3.2 * len(columns), 2.6 * len(chosen)),
                             constrained_layout=True)
    for row, record in enumerate(chosen):
        for col, name in enumerate(columns):
            ax = axes[row, col]
            path = root / record["outputs"][name]
            if name == "defocus":
                coc = load_npy(path)
                limit = max(float(np.abs(coc).max()), 1e-3)
                shown = ax.imshow(coc, cmap="coolwarm", vmin=-limit, vmax=limit)
                fig.colorbar(shown, ax=ax, shrink=0.8, label="CoC (px)")
            else:
                ax.imshow(read_rgb(path))
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(name)
        camera = record["camera"]
        psf = record["psf"]
        axes[row, 0].set_ylabel(
            f"seq {record['sequence']:03d} {camera['name']}\n"
            f"n={psf['n']:g} a={psf['alpha']:g} b={psf['beta']:g}\n"
            f"noise {record['noise_sigma']}", fontsize=8,
        )
    save_figure(fig, output, dpi=100)
    return Path(output)
