"""Where the error lies: PSNR by defocus size, for synthetic data whose defocus maps are known
(ours; the paper reports whole-image means only).

Each pixel falls in a bin of its true |CoC radius| (px, ``{split}_c/defocus/*.npy``, Eq. 1); per
bin and method the squared errors of all images are pooled, so a bin's PSNR is
``-10 log10(sum of squared errors / (pixels x 3))`` over the whole dataset, and its *share* is the
fraction of the method's total squared error that lies there. The share says what to work on: a
bin holding half the remaining error matters more than one with a poor PSNR but few pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualpixel.errors import InputFileError
from dualpixel.io.images import load_npy

__all__ = ["BLUR_BIN_EDGES", "BlurBreakdown", "read_defocus"]

#: Bin edges of |CoC radius| in pixels: in focus (< 1 px), then octaves.
BLUR_BIN_EDGES: tuple[float, ...] = (0.0, 1.0, 2.0, 4.0, 8.0, 16.0, math.inf)


def read_defocus(path: str | Path, shape: tuple[int, int]) -> np.ndarray:
    """A defocus map (signed CoC radius, px) as float32 ``(H, W)``; ``shape`` is the image's."""
    defocus = load_npy(path)
    if defocus.shape != tuple(shape):
        raise InputFileError(path, f"defocus map is {defocus.shape}, the image is {tuple(shape)}")
    return defocus.astype(np.float32, copy=False)


@dataclass
class BlurBreakdown:
    """Squared errors pooled per |CoC| bin and method over a dataset; fill with :meth:`add`."""

    edges: tuple[float, ...] = BLUR_BIN_EDGES
    pixels: np.ndarray = field(init=False)
    squared_error: dict[str, np.ndarray] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        if len(self.edges) < 2 or any(b <= a for a, b in zip(self.edges, self.edges[1:])):
            raise ValueError(f"bin edges must increase, got {self.edges}")
        self.pixels = np.zeros(len(self.edges) - 1, np.int64)

    @property
    def images(self) -> bool:
        """Whether any image has been added."""
        return bool(self.pixels.sum())

    def add(self, defocus: np.ndarray, outputs: dict[str, np.ndarray], target: np.ndarray) -> None:
        """Pool one image: ``defocus`` ``(H, W)`` px, each method's output and the target
        ``(H, W, 3)`` in [0, 1]. Every method must be given for every image."""
        if self.images and set(outputs) != set(self.squared_error):
            raise ValueError(f"methods {sorted(outputs)} differ from the earlier images' "
                             f"{sorted(self.squared_error)}")
        bins = np.digitize(np.abs(defocus), self.edges[1:-1]).ravel()
        count = len(self.edges) - 1
        self.pixels += np.bincount(bins, minlength=count)
        for method, image in outputs.items():
            error = ((image.astype(np.float64) - target) ** 2).sum(axis=-1).ravel()
            pooled = np.bincount(bins, weights=error, minlength=count)
            self.squared_error[method] = self.squared_error.get(method, 0.0) + pooled

    def label(self, index: int) -> str:
        """``"2-4 px"``, ``">= 16 px"``: bin ``index`` for tables and figures."""
        low, high = self.edges[index], self.edges[index + 1]
        return f">= {low:g} px" if math.isinf(high) else f"{low:g}-{high:g} px"

    def table(self) -> list[dict]:
        """Per bin: ``bin``, ``pixel_fraction`` and per method ``psnr`` (None where the bin is
        empty or the error is zero) and ``error_share``."""
        total_pixels = max(int(self.pixels.sum()), 1)
        totals = {m: float(e.sum()) for m, e in self.squared_error.items()}
        rows = []
        for index, pixels in enumerate(self.pixels):
            row: dict = {"bin": self.label(index), "pixel_fraction": pixels / total_pixels,
                         "psnr": {}, "error_share": {}}
            for method, error in self.squared_error.items():
                mse = error[index] / (3 * pixels) if pixels else math.nan
                row["psnr"][method] = -10 * math.log10(mse) if pixels and mse > 0 else None
                row["error_share"][method] = error[index] / totals[method] if totals[method] else 0
            rows.append(row)
        return rows

    def markdown(self) -> str:
        """The table as Markdown: pixels per bin, then each method's PSNR and error share."""
        methods = list(self.squared_error)
        head = "| \\|CoC\\| radius | pixels | " + " | ".join(
            f"{m} PSNR | {m} share of error" for m in methods) + " |"
        lines = [head, "|" + "---|" * (2 + 2 * len(methods))]
        for row in self.table():
            cells = [row["bin"], f"{100 * row['pixel_fraction']:.1f} %"]
            for method in methods:
                value = row["psnr"][method]
                cells += ["–" if value is None else f"{value:.2f}",
                          f"{100 * row['error_share'][method]:.1f} %"]
            lines.append("| " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"
