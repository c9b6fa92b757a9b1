"""Side-by-side comparison figure with zoomed crops (like the paper's Fig. 7 and S6-S8)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualpixel.viz.figures import save_figure

__all__ = ["render_comparison", "sharpest_window"]


def sharpest_window(
    image: np.ndarray, size: int, blurred: np.ndarray | None = None
) -> tuple[int, int]:
    """Top-left corner of the ``size`` window where ``image`` has the most detail that
    ``blurred`` (if given) lacks: where deblurring matters."""

    from dualpixel.filters import gradient_magnitude

    energy = gradient_magnitude(image)
    if blurred is not None:
        energy = energy - gradient_magnitude(blurred)
    return _best_window(energy, size)


def _best_window(score: np.ndarray, size: int) -> tuple[int, int]:
    """Top-left corner of the ``size`` window of ``score`` ``(H, W)`` with the largest mean."""
    from scipy import ndimage

    local = ndimage.uniform_filter(score, size)
    half = size // 2
    inner = local[half : score.shape[0] - half, half : score.shape[1] - half]
    if inner.size == 0:
        return 0, 0
    y, x = np.unravel_index(np.argmax(inner), inner.shape)
    return int(y), int(x)


def largest_gain_window(
    blurred: np.ndarray, restored: np.ndarray, target: np.ndarray, size: int
) -> tuple[int, int]:
    """Top-left corner of the ``size`` window where ``restored`` removes the most squared error
    of ``blurred`` against ``target``: where a method's effect is best seen."""
    gain = ((blurred - target) ** 2 - (restored - target) ** 2).mean(axis=-1)
    return _best_window(gain, size)


def render_comparison(
    panels: dict[str, np.ndarray], path: str | Path, *, crop: int | None = None,
    title: str = "", scores: dict[str, str] | None = None, crop_by: str | None = None,
) -> None:
    """Draw each image (row 1) and the same zoomed crop of each (row 2); write a PNG atomically.

    The crop (outlined in row 1) is the window where the target (or last panel) has the most
    detail that the ``input`` panel lacks, or, with ``crop_by`` naming a panel, the window where
    that panel gains most over ``input`` (:func:`largest_gain_window`).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    names = list(panels)
    reference = panels.get("target", panels[names[-1]])
    height, width = reference.shape[:2]
    crop = crop or max(16, min(height, width) // 4)
    if crop_by is not None and "input" in panels:
        top, left = largest_gain_window(panels["input"], panels[crop_by], reference, crop)
    else:
        top, left = sharpest_window(reference, crop, panels.get("input"))
    fig, axes = plt.subplots(2, len(names), figsize=(3.2 * len(names), 3.2 * height / width + 3.4),
                             squeeze=False)
    for column, name in enumerate(names):
        image = np.clip(panels[name], 0, 1)
        label = name if not scores or name not in scores else f"{name}\n{scores[name]}"
        axes[0, column].imshow(image)
        axes[0, column].add_patch(Rectangle((left, top), crop, crop, fill=False, color="yellow"))
        axes[0, column].set_title(label, fontsize=9)
        axes[1, column].imshow(image[top : top + crop, left : left + crop], interpolation="nearest")
        for row in (0, 1):
            axes[row, column].axis("off")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
