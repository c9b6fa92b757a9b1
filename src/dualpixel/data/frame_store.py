"""Decoded training frames on disk, memory-mapped: decode each PNG once, share it across processes.

Decoding a frame's three PNGs (views and target, 840x560) takes ~30 ms on one core, several times
the rest of a training item. An in-memory cache (``DPPatchDataset(cache=True)``) is per process
and lost when loader processes end (every epoch in training). A store instead
writes each frame's views and target once as one ``.npy`` file (``(roles, H, W, 3)``, uint8 where
that is lossless, else float32) and every process maps it read-only: the operating system's page
cache holds one copy for all, and cropping a patch touches only its rows.

On-the-fly sources keep their scenes' RGB and depth there too (:meth:`FrameStore.load_scene`),
decoded by whichever loader process first renders a crop of them.

Files are named by a hash of the frame's source paths, sizes and modification times, so an edited
source is decoded again, never served stale; entries are written atomically, so processes racing
on the same frame are safe. Old entries are never removed: delete the folder to reclaim it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dualpixel.data.layout import DPFramePaths, read_frame
from dualpixel.errors import InputFileError
from dualpixel.io.atomic import atomic_path

__all__ = ["FrameStore", "compact_frame", "expand"]


def _compact(image: np.ndarray) -> np.ndarray:
    """``image`` (float32 in [0, 1]) as uint8 if it holds 8-bit values exactly, else unchanged."""
    as_bytes = np.round(image * 255.0).astype(np.uint8)
    return as_bytes if np.array_equal(as_bytes.astype(np.float32) / 255.0, image) else image


def compact_frame(images: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A decoded frame with each image as uint8 where that is lossless (4x less memory)."""
    return {key: _compact(image) for key, image in images.items()}


def expand(image: np.ndarray) -> np.ndarray:
    """The inverse of :func:`compact_frame` for one image (or a crop): float32 in [0, 1]."""
    return image.astype(np.float32) / 255.0 if image.dtype == np.uint8 else image


class FrameStore:
    """Decoded frames under ``folder`` (created on first use); :meth:`load` decodes a frame once."""

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise InputFileError(self.folder, "frame store must be a folder, found a file")

    def entry(self, frame: DPFramePaths) -> Path:
        """The file that holds ``frame`` (it may not exist yet)."""
        roles = (("left", frame.left), ("right", frame.right), ("target", frame.target))
        return self.folder / f"{_digest(roles)}.npy"

    def scene_entries(self, rgb: Path, depth: Path, settings: str) -> tuple[Path, Path]:
        """The files that hold an RGB-D scene frame (its ``rgb`` and ``depth`` files, read with
        ``settings``): its RGB and its depth."""
        name = _digest((("rgb", rgb), ("depth", depth)), settings)
        return self.folder / f"{name}.rgb.npy", self.folder / f"{name}.depth.npy"

    def load_scene(self, rgb: Path, depth: Path, settings: str,
                   decode: Callable[[], tuple[np.ndarray, np.ndarray]]
                   ) -> tuple[np.ndarray, np.ndarray]:
        """A scene frame's RGB ``(H, W, 3)`` (uint8 where that is lossless, else float32 in
        [0, 1]) and depth ``(H, W)`` float32, read-only and mapped from the store; ``decode()``
        reads them from ``rgb`` and ``depth`` (with ``settings``) for the first process that
        asks (training crops rendered on the fly read a whole scene for each crop)."""
        paths = self.scene_entries(rgb, depth, settings)
        if not all(path.is_file() for path in paths):
            image, distance = decode()
            self.folder.mkdir(parents=True, exist_ok=True)
            for path, array in zip(paths[::-1], (distance.astype(np.float32), _compact(image))):
                with atomic_path(path) as tmp:  # the RGB last: it marks the entry whole
                    np.save(tmp, array)
        return tuple(_mapped(path) for path in paths)

    def load(self, frame: DPFramePaths) -> dict[str, np.ndarray]:
        """``left``, ``right`` (and ``target``) as read-only ``(H, W, 3)`` arrays, uint8 or
        float32 in [0, 1] (see :func:`compact_frame`), mapped from the store. Mapped anew on each
        call (0.07 ms): a map holds a file descriptor, and keeping one per frame would exhaust
        the usual limit of 1,024 on a dataset of thousands of frames."""
        roles = ["left", "right"] + (["target"] if frame.target is not None else [])
        path = self.entry(frame)
        if not path.is_file():
            images = compact_frame(read_frame(frame))
            if all(images[r].dtype == np.uint8 for r in roles):
                stacked = np.stack([images[r] for r in roles])
            else:
                stacked = np.stack([expand(images[r]).astype(np.float32) for r in roles])
            self.folder.mkdir(parents=True, exist_ok=True)
            with atomic_path(path) as tmp:
                np.save(tmp, stacked)
        mapped = _mapped(path)
        return {role: mapped[index] for index, role in enumerate(roles)}


def _digest(paths, settings: str = "") -> str:
    """A hash of ``(role, path)`` files' resolved paths, sizes and modification times (and
    ``settings``): an edited source gets a new entry."""
    digest = hashlib.sha1(settings.encode())
    for role, path in paths:
        if path is None:
            continue
        try:
            stat = path.stat()
        except OSError as error:
            raise InputFileError(path, f"cannot be read ({error.strerror})") from None
        digest.update(f"{role}\0{path.resolve()}\0{stat.st_size}\0{stat.st_mtime_ns}\n"
                      .encode())
    return digest.hexdigest()


def _mapped(path: Path) -> np.ndarray:
    try:
        return np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as error:
        raise InputFileError(path, f"frame store entry cannot be read ({error}); delete it "
                                   "to decode the frame again") from None

