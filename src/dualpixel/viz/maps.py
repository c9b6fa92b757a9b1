"""Small pictures of a DP frame: a colour-mapped map (depth, defocus) and the views as a GIF."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualpixel.io.atomic import atomic_path
from dualpixel.viz.figures import save_figure

__all__ = ["render_colour_map", "write_views_gif"]


def render_colour_map(values: np.ndarray, path: str | Path, label: str, *, cmap: str,
                      symmetric: bool = False) -> Path:
    """A ``(H, W)`` map with a colour bar (``symmetric``: limits +-max|value|, zero in the
    middle of the colour map)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    height, width = values.shape
    fig, ax = plt.subplots(figsize=(5.2, 5.2 * height / width + 0.3))
    limit = float(np.abs(values).max()) or 1.0
    shown = ax.imshow(values, cmap=cmap, vmin=-limit if symmetric else None,
                      vmax=limit if symmetric else None)
    fig.colorbar(shown, ax=ax, fraction=0.046, pad=0.04, label=label)
    ax.axis("off")
    fig.tight_layout()
    return save_figure(fig, path, dpi=100)


def write_views_gif(left: np.ndarray, right: np.ndarray, path: str | Path) -> Path:
    """An animated GIF alternating the left and right views (how DP disparity is usually shown)."""
    from PIL import Image

    frames = [Image.fromarray((np.clip(v, 0, 1) * 255 + 0.5).astype(np.uint8)) for v in
              (left, right)]
    with atomic_path(path) as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=600,
                       loop=0)
    return Path(path)
