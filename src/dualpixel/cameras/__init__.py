"""Camera files that ship with the package, by name (``synth --camera canon-840-linear``,
``synthesize(camera="pixel4")``, ``camera: pixel4`` in a recipe).

- ``canon-840``, ``canon-hd``: the Canon EOS 5D Mark IV measured on the seven Canon dev pairs at
  840x512 and 1620x980 by ``dualpixel calibrate camera`` (PSF shape, per-channel disparity
  ratios, blur sizes; blur in the stored values);
- ``canon-840-linear``, ``canon-hd-linear``: the same cameras with blur in linear light;
- ``pixel4``: the Google Pixel 4, made by ``dualpixel calibrate fit-psf --camera`` from its
  measured DP PSFs (green-only views, linear light).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["camera_names", "shipped_camera"]


def camera_names() -> list[str]:
    """Names of the shipped camera files, sorted."""
    folder = resources.files(__name__)
    return sorted(entry.name[:-5] for entry in folder.iterdir() if entry.name.endswith(".json"))


def shipped_camera(name: str) -> Path | None:
    """The file of the shipped camera ``name``, or None when no camera has that name."""
    if name not in camera_names():
        return None
    return Path(str(resources.files(__name__).joinpath(f"{name}.json")))
