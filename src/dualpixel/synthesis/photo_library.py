"""A folder of real photographs as the surfaces of synthetic scenes (``scenes --photos DIR``).

Defocus deblurring learns what blurred real texture looks like from what it is trained on, so
the "photographic" scene layout (:mod:`dualpixel.synthesis.scenes`) covers most of its frame with
photographs: whole photographs as far planes and walls, regions of one photograph at several
depths, photo-textured objects. This module finds, checks and serves those photographs:

- a folder's images (``.jpg``, ``.jpeg``, ``.png``, ``.tif``, ``.tiff``, ``.bmp``, ``.webp``; other
  files are ignored) are each decoded once when the library is made, so that an unreadable file is
  named before any work (``skip_bad``: named in a warning and left out instead);
- photographs are never enlarged: a texture is a photograph shown at a scale of at most 1 (a
  sharp target must stay sharp); one whose shorter side is below the scenes' smallest texture
  (:attr:`PhotoLibrary.min_side`) is left out, and a folder left with none is refused;
- grey photographs are used as grey RGB; 16-bit files as their 16 bits.

The library pickles as its list of files (worker processes decode what they use, once each).
"""

from __future__ import annotations

import functools
import hashlib
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from dualpixel.errors import InputFileError, ParameterError, check_range

__all__ = ["PHOTO_SUFFIXES", "PhotoLibrary", "shipped_library"]

#: Files of a photo folder that are read as photographs (case-insensitive).
PHOTO_SUFFIXES: tuple[str, ...] = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp")


@functools.lru_cache(maxsize=32)
def _decoded(path: str) -> np.ndarray:
    """One photograph as float32 ``(H, W, 3)`` RGB in [0, 1] (grey copied to RGB), cached per
    process (a scene draws several textures from the same photographs)."""
    from dualpixel.io.images import read_rgb

    return read_rgb(path)


@dataclass(frozen=True)
class PhotoLibrary:
    """Photographs to texture scenes with: ``paths`` and their ``sizes`` ``(H, W)`` in pixels.

    Made by :meth:`from_folder` (a user's folder, checked) or :func:`shipped_library` (the
    package's small set). ``min_side``: the shortest side a photograph has to have (px).
    """

    folder: str
    paths: tuple[str, ...]
    sizes: tuple[tuple[int, int], ...]
    min_side: int

    @classmethod
    def from_folder(cls, folder: str | Path, *, min_side: int = 64, skip_bad: bool = False,
                    ) -> PhotoLibrary:
        """The photographs directly in ``folder`` (sorted by name), each decoded once to check it.

        Raises :class:`InputFileError` naming the folder when it is missing, holds no image
        file, no readable one, or only photographs with a side below ``min_side``; naming the
        file when one cannot be read (unless ``skip_bad``: a warning names it and it is left out).
        """
        check_range("min_side", min_side, 1)
        root = Path(folder)
        if not root.is_dir():
            raise InputFileError(root, "photo folder not found (give a folder of photographs)")
        files = sorted(p for p in root.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES
                       and not p.name.startswith(".") and p.is_file())
        if not files:
            raise InputFileError(root, "holds no photographs (files ending "
                                       f"{', '.join(PHOTO_SUFFIXES)}); give a folder of them")
        paths, sizes, small, bad = [], [], [], []
        for path in files:
            try:
                height, width = _decoded(str(path)).shape[:2]
            except InputFileError as error:
                if not skip_bad:
                    raise InputFileError(path, f"{error.problem}; --skip-bad leaves "
                                               "unreadable photographs out") from None
                bad.append(path.name)
                continue
            finally:
                _decoded.cache_clear()  # checking a folder must not hold it all in memory
            if min(height, width) < min_side:
                small.append((path.name, width, height))
                continue
            paths.append(str(path))
            sizes.append((height, width))
        if bad:
            warnings.warn(f"{root}: left out {len(bad)} unreadable file(s): "
                          f"{', '.join(bad[:5])}{' ...' if len(bad) > 5 else ''}", stacklevel=2)
        if not paths:
            if small:
                largest = max(small, key=lambda s: min(s[1], s[2]))
                raise InputFileError(root, f"every photograph is smaller than the scenes' "
                                           f"textures (shorter side below {min_side} px; the "
                                           f"largest, {largest[0]}, is {largest[1]}x{largest[2]})"
                                           "; give larger photographs or smaller scenes")
            raise InputFileError(root, "holds no readable photograph")
        if small:
            warnings.warn(f"{root}: left out {len(small)} photograph(s) with a side below "
                          f"{min_side} px (they would have to be enlarged): "
                          f"{', '.join(s[0] for s in small[:5])}"
                          f"{' ...' if len(small) > 5 else ''}", stacklevel=2)
        return cls(str(root), tuple(paths), tuple(sizes), int(min_side))

    def __len__(self) -> int:
        return len(self.paths)

    def describe(self) -> dict[str, object]:
        """What a scene folder records of its photographs: the folder as given, the count and
        a digest of the files' names and byte sizes (another folder's content is noticed)."""
        digest = hashlib.sha256()
        for path in self.paths:
            digest.update(f"{Path(path).name}:{Path(path).stat().st_size}\n".encode())
        return {"folder": self.folder, "photographs": len(self.paths),
                "digest": digest.hexdigest()[:16]}

    def image(self, index: int) -> np.ndarray:
        """Photograph ``index``, float32 ``(H, W, 3)`` RGB in [0, 1]."""
        return _decoded(self.paths[index])

    def covering(self, height: int, width: int) -> np.ndarray:
        """Indices of the photographs that cover ``height x width`` px without being enlarged."""
        sizes = np.array(self.sizes).reshape(-1, 2)
        return np.flatnonzero((sizes[:, 0] >= height) & (sizes[:, 1] >= width))

    def crop(self, rng: np.random.Generator, height: int, width: int, *,
             index: int | None = None) -> np.ndarray:
        """A ``(height, width, 3)`` float32 region of one photograph (``index``, else drawn among
        those that cover it): shown at a scale drawn log-uniformly in [1/4, 3/4], or the
        smallest that covers the region where that is larger (never above 1: never enlarged),
        at a random position, maybe mirrored.

        Raises :class:`ParameterError` when no photograph covers the region (see
        :meth:`texture`, which tiles then).
        """
        if index is None:
            candidates = self.covering(height, width)
            if not len(candidates):
                raise ParameterError(f"no photograph covers {width}x{height} px")
            index = int(candidates[int(rng.integers(len(candidates)))])
        photo = self.image(index)
        low = max(height / photo.shape[0], width / photo.shape[1])
        if low > 1.0:
            raise ParameterError(f"{self.paths[index]} does not cover {width}x{height} px")
        # shown at 1/4 to 3/4 of its size unless it must be larger to cover the region: denser
        # detail is as real as the original's, and a JPEG's 8-px blocks are resampled away
        low_scale, high_scale = max(low, 0.25), max(low, 0.75)
        scale = float(np.exp(rng.uniform(np.log(low_scale), np.log(high_scale))))
        scale = min(max(scale, low), 1.0)
        if scale < 1.0:
            size = (max(width, round(photo.shape[1] * scale)),
                    max(height, round(photo.shape[0] * scale)))
            photo = cv2.resize(photo, size, interpolation=cv2.INTER_AREA)
        y0 = int(rng.integers(photo.shape[0] - height + 1))
        x0 = int(rng.integers(photo.shape[1] - width + 1))
        region = photo[y0 : y0 + height, x0 : x0 + width]
        if rng.uniform() < 0.5:
            region = region[:, ::-1]
        return np.ascontiguousarray(region, dtype=np.float32)

    def texture(self, rng: np.random.Generator, height: int, width: int
                ) -> tuple[np.ndarray, np.ndarray]:
        """A region covered by photographs: ``(rgb (H, W, 3) float32, tiles (H, W) int32)``.

        A photograph is drawn, every one alike: the region is that photograph when it covers
        the region (``tiles`` all 0), else a grid of photographs that do cover their tiles,
        each tile one of them (``tiles`` numbers the tiles, so that each can be given its own
        depth, as walls side by side).
        """
        index = int(rng.integers(len(self.paths)))
        if min(self.sizes[index][0] / height, self.sizes[index][1] / width) >= 1.0:
            return (self.crop(rng, height, width, index=index),
                    np.zeros((height, width), np.int32))
        # tiles that three photographs in four cover, so that many take turns
        side = max(int(np.percentile([min(s) for s in self.sizes], 25)), self.min_side)
        rows, cols = -(-height // side), -(-width // side)
        ys = np.linspace(0, height, rows + 1).round().astype(int)
        xs = np.linspace(0, width, cols + 1).round().astype(int)
        rgb = np.empty((height, width, 3), np.float32)
        tiles = np.empty((height, width), np.int32)
        for i in range(rows):
            for j in range(cols):
                h, w = ys[i + 1] - ys[i], xs[j + 1] - xs[j]
                rgb[ys[i] : ys[i + 1], xs[j] : xs[j + 1]] = self.crop(rng, h, w)
                tiles[ys[i] : ys[i + 1], xs[j] : xs[j + 1]] = i * cols + j
        return rgb, tiles


def shipped_library(min_side: int = 64) -> PhotoLibrary:
    """The package's own small set of photographs (:mod:`dualpixel.synthesis.textures`), for the
    "photographic" layout without ``--photos`` (tests, the demo)."""
    from dualpixel.synthesis.textures import PHOTOGRAPH_NAMES

    folder = Path(str(resources.files("dualpixel.synthesis").joinpath("photographs")))
    paths = [str(folder / f"{name}.png") for name in PHOTOGRAPH_NAMES]
    sizes = [tuple(_decoded(p).shape[:2]) for p in paths]
    _decoded.cache_clear()
    keep = [k for k, s in enumerate(sizes) if min(s) >= min_side]
    if not keep:
        raise ParameterError(f"the shipped photographs are all smaller than {min_side} px")
    return PhotoLibrary("(shipped)", tuple(paths[k] for k in keep),
                        tuple(sizes[k] for k in keep), int(min_side))
