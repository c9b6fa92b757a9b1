"""Google Pixel dual-pixel captures (left/right 16-bit PNGs) to a DPDD-layout folder.

The public Pixel DP releases store each capture as two single-channel 16-bit PNGs, the left and
right DP views of one green channel of the raw frame, linear in light above a black level,
under names such as ``result_leftPd_center.png`` / ``result_rightPd_center.png`` or
``left.png`` / ``right.png`` in one folder per capture. In the stored orientation the DP
baseline is vertical (content shifts up and down between the views), while the models take a
horizontal baseline with the left view's defocused content to the left of the right view's
behind the focus plane: a 90-degree turn counter-clockwise (``rotate="ccw"``, as the DPDNet
authors' own test code turns portrait frames) makes the stored orientation fit.

:func:`import_pixel_dp` finds the two views of each capture folder, checks them (16-bit or 8-bit
grey, one size), turns them and writes ``{split}_l/source``, ``{split}_r/source`` and, as the
views' mean, ``{split}_c/source``, ready for ``dualpixel deblur --input OUT --encoding linear
--black-level B --white-level W`` (levels in the files' units; the releases' metadata give them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.images import IMAGE_SUFFIXES, read_view

__all__ = ["ROTATIONS", "find_pixel_views", "import_pixel_dp"]

#: Turns applied to the stored views: counter-clockwise (the Pixel releases), clockwise, none.
ROTATIONS = {"ccw": 1, "cw": -1, "none": 0}


def _is_view(path: Path, side: str) -> bool:
    return path.suffix.lower() in IMAGE_SUFFIXES and side in path.stem.lower()


def find_pixel_views(folder: str | Path) -> tuple[Path, Path]:
    """The left and right view files of one capture folder: the one image whose name holds
    "left" and the one whose name holds "right" (any case: ``result_leftPd_center.png``)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, "not a folder (give one folder per capture)")
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    found = {}
    for side in ("left", "right"):
        matches = [p for p in files if _is_view(p, side)]
        if len(matches) != 1:
            what = "no image" if not matches else f"{len(matches)} images"
            raise InputFileError(folder, f"{what} with '{side}' in the name; a capture folder "
                                         "holds one left and one right view")
        found[side] = matches[0]
    return found["left"], found["right"]


def _read_grey(path: Path) -> tuple[np.ndarray, int]:
    view, bits = read_view(path)
    if view.shape[2] != 1:
        raise InputFileError(path, "is a colour image; Pixel DP views are single-channel grey")
    return view[:, :, 0], bits


def _read_pair(left_path: Path, right_path: Path) -> tuple[np.ndarray, np.ndarray, int]:
    (left, bits), (right, right_bits) = _read_grey(left_path), _read_grey(right_path)
    if left.shape != right.shape or bits != right_bits:
        raise InputFileError(right_path, f"{right.shape[1]}x{right.shape[0]} {right_bits}-bit "
                                         f"differs from {left_path.name} ({left.shape[1]}x"
                                         f"{left.shape[0]} {bits}-bit)")
    return left, right, bits


def import_pixel_dp(captures: list[str | Path], output: str | Path, *, split: str = "test",
                    rotate: str = "ccw", progress: bool = False) -> list[tuple[str, Path, Path]]:
    """Write every capture folder's views into a DPDD-layout folder under the capture's name,
    turned by ``rotate`` (:data:`ROTATIONS`), at their own bit depth; the combined image is
    their mean. Everything is checked before the first file is written. Returns
    ``(name, left file, right file)`` per capture."""
    from dualpixel.io.atomic import check_writable
    from dualpixel.io.images import write_png
    from dualpixel.io.paths import check_plain_name
    from dualpixel.progress import progress_bar

    if rotate not in ROTATIONS:
        raise ParameterError(f"rotate must be one of {', '.join(ROTATIONS)}, got {rotate!r}")
    check_plain_name(split, "split")
    captures = [Path(c) for c in captures]
    names = [c.resolve().name for c in captures]
    if len(set(names)) < len(names):
        raise ParameterError("two capture folders share a name; import them separately")
    pairs = [find_pixel_views(c) for c in captures]
    output = Path(output)
    folders = {role: output / f"{split}_{role}" / "source" for role in ("l", "r", "c")}
    for folder in folders.values():
        check_writable(folder / "probe.png")
    for left_path, right_path in pairs:  # every capture checked before anything is written
        _read_pair(left_path, right_path)
    results = []
    turn = ROTATIONS[rotate]
    for name, (left_path, right_path) in progress_bar(list(zip(names, pairs, strict=True)),
                                                      desc="importing", unit="capture",
                                                      enabled=progress):
        left, right, bits = _read_pair(left_path, right_path)
        left, right = np.rot90(left, turn), np.rot90(right, turn)
        for role, image in (("l", left), ("r", right), ("c", 0.5 * (left + right))):
            write_png(folders[role] / f"{name}.png", np.ascontiguousarray(image), bit_depth=bits)
        results.append((name, left_path, right_path))
    return results
