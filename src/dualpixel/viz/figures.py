"""Saving matplotlib figures: one helper, so every figure is written the same way."""

from __future__ import annotations

from pathlib import Path

from dualpixel.errors import OutputFileError
from dualpixel.io.atomic import atomic_path

__all__ = ["FIGURE_FORMATS", "check_figure_path", "save_figure"]

#: Suffixes a figure may be written to.
FIGURE_FORMATS = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def check_figure_path(path: str | Path) -> Path:
    """Refuse a figure path that is a folder or has no known format (before any work)."""
    path = Path(path)
    if path.is_dir():
        raise OutputFileError(path, "is a folder; give a file name such as figure.png")
    if path.suffix.lower() not in FIGURE_FORMATS:
        raise OutputFileError(path, f"unknown figure format {path.suffix or '(no suffix)'}; "
                                    f"use one of {', '.join(FIGURE_FORMATS)}")
    return path


def save_figure(fig, path: str | Path, *, dpi: int = 110) -> Path:
    """Write ``fig`` atomically in the format of ``path``'s suffix and close it."""
    import matplotlib.pyplot as plt

    path = check_figure_path(path)
    try:
        with atomic_path(path) as tmp:
            # bbox "tight": labels that a layout pushed past the canvas are kept, not cut
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", pad_inches=0.08,
                        format=path.suffix.lower().lstrip(".").replace("jpg", "jpeg"))
    finally:
        plt.close(fig)
    return path
