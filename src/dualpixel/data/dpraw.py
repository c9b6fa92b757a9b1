"""Canon Dual Pixel RAW (.CR2) files to left, right and combined views.

A DPRAW file holds two raw frames: the first is the whole pixel (A+B, the photograph), the second
the A sub-pixels alone; LibRaw reaches the second with ``shot_select=1`` (rawpy >= 0.28, the
``raw`` extra: ``pip install 'dualpixel[raw]'``). A DNG holding both is read the same way when its
CFA image has two samples per pixel (A+B, A): LibRaw reads a DNG's second frame only so, not from
a second raw image. After the black level, B = (A+B) - A.

The development is deliberately simple and documented, the same for all three images:

1. black level subtracted, scaled by the white level to [0, 1] (linear); where the combined
   frame clipped and A did not, B = (A+B) - A is too dark, and B is estimated as A there (the
   two halves of a pixel see nearly the same light in highlights; :attr:`DualPixelViews.clipped`
   says on what share of the frame, and the import warns);
2. the views doubled, so that each is as bright as the combined image (the DPDD convention the
   models are trained on: the combined image is the views' mean);
3. the camera's white balance (as shot) per colour site, clipped to [0, 1];
4. demosaicing (OpenCV, edge-aware bilinear), then the camera's colour matrix from white-balanced
   camera RGB to linear sRGB, as LibRaw develops (its ``color_matrix`` for the file: the same
   patch colours as ``rawpy``'s ``postprocess`` within 1e-3, tested), clipped to [0, 1];
5. the sRGB transfer curve, the encoding of the photographs the training data is made from;
6. optionally (``scale`` < 1) an area-averaging downscale: the shipped models were trained on
   the blur of 840- to 1680-px-wide frames, and a full 6720-px frame of a 30 MP camera carries
   four to eight times that blur (the import warns on frames over :data:`MODEL_WIDTH` x 2).

CR3 files (EOS R, R5 and later) are not supported: only CR2 Dual Pixel RAW has been read here.

Which of A and B is the left view is decided by measurement (``a_view="auto"``): in most
photographs the defocused content lies behind the focus plane, where the right view shows it
shifted to the right of the left view's (the convention of the Canon DPDD pairs and of our
synthetic data; :func:`~dualpixel.data.statistics.defocus_shift_counts` counts it and
:mod:`dualpixel.inference.view_checks` warns on pairs that break it). The assignment under
which most defocused regions shift that way is taken; when too few regions are defocused to
tell, A is the left view, and the result says so.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from dualpixel.data.statistics import defocus_shift_counts
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.images import quantise
from dualpixel.optics.tone import linear_to_srgb_array

__all__ = [
    "DualPixelRaw",
    "DualPixelViews",
    "camera_colour_matrix",
    "develop_mosaic",
    "develop_views",
    "import_dual_pixel_raws",
    "read_dual_pixel_raw",
    "split_dual_pixel",
]

A_VIEWS = ("auto", "left", "right")
#: Widest frames (px) the shipped models' training blur was made for.
MODEL_WIDTH = 1680
#: A raw value at or above this share of the white level counts as clipped.
CLIP_LEVEL = 0.995
_LIBRAW_FLIP_TO_EXIF = {0: 1, 3: 3, 5: 8, 6: 6}
#: Linear sRGB (D65) -> CIE XYZ, as dcraw and LibRaw use it.
_XYZ_FROM_SRGB = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169],
                           [0.019334, 0.119193, 0.950227]])
#: OpenCV's demosaicing code for each 2x2 pattern (OpenCV names it from the second row).
_DEMOSAIC = {"RGGB": cv2.COLOR_BayerBG2RGB_EA, "BGGR": cv2.COLOR_BayerRG2RGB_EA,
             "GRBG": cv2.COLOR_BayerGB2RGB_EA, "GBRG": cv2.COLOR_BayerGR2RGB_EA}


@dataclass(frozen=True)
class DualPixelRaw:
    """The two raw frames of a DPRAW file and what developing them needs.

    ``combined`` (A+B) and ``a_only`` are ``(H, W)`` raw mosaics (sensor counts); ``pattern`` the
    2x2 colour filter layout as letters (``"RGGB"`` ...); ``black_level`` per site ``(2, 2)``;
    ``white_balance`` the as-shot multipliers (R, G, B), green 1.
    """

    combined: np.ndarray
    a_only: np.ndarray
    pattern: str
    black_level: np.ndarray
    white_level: float
    white_balance: tuple[float, float, float]
    orientation: int = 1  # EXIF orientation of the photograph (the pixels stay as stored)
    #: ``(3, 3)`` white-balanced camera RGB -> linear sRGB; None: camera RGB kept.
    colour_matrix: np.ndarray | None = None


@dataclass(frozen=True)
class DualPixelViews:
    """Developed ``(H, W, 3)`` float32 images in [0, 1] and how the views were assigned."""

    left: np.ndarray
    right: np.ndarray
    combined: np.ndarray
    a_view: str  # "left" or "right": which view the A sub-pixels gave
    evidence: str  # how a_view was decided
    clipped: float = 0.0  # share of the frame where A+B clipped and A did not (B estimated)
    #: share of the frame where A is brighter than A+B beyond noise (B is zero there): frames
    #: swapped, or not a DPRAW pair
    inverted: float = 0.0


def _rawpy():
    try:
        import rawpy
    except ImportError:
        raise ParameterError("reading camera raw files needs rawpy: pip install "
                             "'dualpixel[raw]'") from None
    return rawpy


def camera_colour_matrix(raw) -> np.ndarray | None:
    """The ``(3, 3)`` matrix from white-balanced camera RGB to linear sRGB that LibRaw develops a
    file with (a ``rawpy`` raw object's ``color_matrix``; from its ``rgb_xyz_matrix`` by dcraw's
    rule where that is all the file gives); None when the file carries neither."""
    matrix = np.asarray(getattr(raw, "color_matrix", np.zeros((3, 4))), np.float64)[:3, :3]
    if matrix.shape == (3, 3) and np.isfinite(matrix).all() and np.abs(matrix).sum() > 0:
        return matrix
    cam_xyz = np.asarray(getattr(raw, "rgb_xyz_matrix", np.zeros((4, 3))), np.float64)[:3, :3]
    if cam_xyz.shape != (3, 3) or not np.isfinite(cam_xyz).all() or not np.abs(cam_xyz).sum():
        return None
    cam_rgb = cam_xyz @ _XYZ_FROM_SRGB
    rows = cam_rgb.sum(axis=1, keepdims=True)
    if np.any(np.abs(rows) < 1e-9):
        return None
    return np.linalg.pinv(cam_rgb / rows)  # each row of cam_rgb sums to 1: white stays white


def read_dual_pixel_raw(path: str | Path) -> DualPixelRaw:
    """Both frames of a Canon Dual Pixel RAW file (rawpy/LibRaw)."""
    rawpy = _rawpy()
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "file not found")
    try:
        with rawpy.imread(str(path)) as raw:
            combined = raw.raw_image_visible.copy()
            colors = raw.color_desc.decode("ascii")
            indices = np.asarray(raw.raw_pattern)
            black = np.asarray(raw.black_level_per_channel, np.float64)
            white = float(raw.white_level)
            balance = [float(v) for v in raw.camera_whitebalance]
            orientation = _LIBRAW_FLIP_TO_EXIF.get(int(raw.sizes.flip), 1)
            colour_matrix = camera_colour_matrix(raw)
    except rawpy.LibRawError as error:
        reason = error.args[0] if error.args else error
        if isinstance(reason, bytes):  # LibRaw's messages arrive as bytes
            reason = reason.decode("utf-8", "replace")
        raise InputFileError(path, f"cannot be read as a camera raw file ({reason})") from None
    try:
        with rawpy.imread(str(path), shot_select=1) as raw:
            a_only = raw.raw_image_visible.copy()
    except rawpy.LibRawError:
        a_only = None
    if a_only is None or a_only.shape != combined.shape or np.array_equal(a_only, combined):
        raise InputFileError(path, "holds one raw frame, not a Dual Pixel RAW's two (A+B and "
                                   "A); shoot with Dual Pixel RAW on")
    if indices.shape != (2, 2) or len(colors) < 3:
        raise InputFileError(path, f"colour filter layout {indices.tolist()} ({colors}) is not "
                                   "a 2x2 Bayer pattern")
    if not np.isfinite(white) or not np.all(black[indices] < white):
        raise InputFileError(path, f"its white level {white:g} is not above its black level "
                                   f"{black.max():g}: the file's levels are damaged")
    pattern = "".join(colors[i] for i in indices.ravel())
    green = balance[1] if balance[1] > 0 else 1.0
    white_balance = tuple(v / green if v > 0 else 1.0 for v in balance[:3])
    return DualPixelRaw(combined, a_only, pattern, black[indices], white, white_balance,
                        orientation, colour_matrix)


def _per_site(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A ``(2, 2)`` value per colour-filter site repeated over a mosaic of ``shape``."""
    height, width = shape
    return np.tile(values, (height // 2 + 1, width // 2 + 1))[:height, :width]


def split_dual_pixel(raw: DualPixelRaw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear ``(H, W)`` mosaics ``(A, B, A+B)`` in units of the white level, black removed,
    the views doubled to the combined image's brightness (steps 1-2 of the module docstring)."""
    return _split(raw, _clipped_sites(raw))


def _split(raw: DualPixelRaw, clipped: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`split_dual_pixel` with the clipped sites (:func:`_clipped_sites`) given."""
    black = _per_site(raw.black_level, raw.combined.shape)
    scale = raw.white_level - black
    if np.any(scale <= 0):
        raise ParameterError(f"white level {raw.white_level} is not above the black level")
    combined = np.clip((raw.combined - black) / scale, 0.0, None)
    a_only = np.clip((raw.a_only - black) / scale, 0.0, None)
    b_only = np.clip(combined - a_only, 0.0, None)
    b_only[clipped] = a_only[clipped]  # the sum clipped: B from A, not from the clipped sum
    return (2.0 * a_only).astype(np.float32), (2.0 * b_only).astype(np.float32), \
        combined.astype(np.float32)


#: A counts as brighter than A+B where it exceeds it by this share of the white level (noise
#: keeps A below A+B by half a view's light; photon noise alone does not reach this).
INVERTED_MARGIN = 0.02


def _inverted_share(raw: DualPixelRaw, clipped: np.ndarray) -> float:
    """Share of the sites where A exceeds A+B by :data:`INVERTED_MARGIN` of the white level
    (sites where A+B clipped left out): B = (A+B) - A is clipped to zero there."""
    excess = raw.a_only.astype(np.float64) - raw.combined.astype(np.float64)
    return float(((excess > INVERTED_MARGIN * raw.white_level) & ~clipped).mean())


def _clipped_sites(raw: DualPixelRaw) -> np.ndarray:
    """Sites where the combined frame reached the white level and the A frame did not."""
    level = CLIP_LEVEL * raw.white_level
    return (raw.combined >= level) & (raw.a_only < level)


def develop_mosaic(mosaic: np.ndarray, pattern: str,
                   white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0),
                   colour_matrix: np.ndarray | None = None) -> np.ndarray:
    """A linear ``(H, W)`` mosaic in [0, 1] to an sRGB-encoded ``(H, W, 3)`` float32 image
    (steps 3-5 of the module docstring; ``colour_matrix`` None: camera RGB kept)."""
    if pattern not in _DEMOSAIC:
        raise ParameterError(f"Bayer pattern must be one of {', '.join(_DEMOSAIC)}, "
                             f"got {pattern!r}")
    gains = {"R": white_balance[0], "G": white_balance[1], "B": white_balance[2]}
    site_gain = np.array([[gains[pattern[0]], gains[pattern[1]]],
                          [gains[pattern[2]], gains[pattern[3]]]], np.float32)
    balanced = mosaic * _per_site(site_gain, mosaic.shape)
    levels = quantise(balanced, 16)
    rgb = cv2.cvtColor(levels, _DEMOSAIC[pattern]).astype(np.float32) / 65535.0
    if colour_matrix is not None:
        rgb = np.clip(rgb @ np.asarray(colour_matrix, np.float32).T, 0.0, 1.0)
    return linear_to_srgb_array(rgb)


def develop_views(raw: DualPixelRaw, *, a_view: str = "auto", scale: float = 1.0
                  ) -> DualPixelViews:
    """Left, right and combined images of a DPRAW capture; ``a_view``: ``"left"``, ``"right"``
    or ``"auto"`` (by measurement, see the module docstring); ``scale`` in (0, 1]: the images'
    size as a fraction of the frame's (area-averaged)."""
    if a_view not in A_VIEWS:
        raise ParameterError(f"a_view must be one of {', '.join(A_VIEWS)}, got {a_view!r}")
    _check_scale(scale)
    clipped = _clipped_sites(raw)
    a_mosaic, b_mosaic, combined_mosaic = _split(raw, clipped)
    a_image, b_image, combined = (_resized(develop_mosaic(m, raw.pattern, raw.white_balance,
                                                          raw.colour_matrix), scale)
                                  for m in (a_mosaic, b_mosaic, combined_mosaic))
    if a_view == "auto":
        counts = defocus_shift_counts(a_image, b_image)
        if counts is None or counts[0] == counts[1]:
            a_view, evidence = "left", "too few defocused regions to tell; A taken as left"
        else:
            behind, front = counts
            a_view = "left" if behind > front else "right"
            evidence = (f"{max(counts)} of {sum(counts)} defocused regions shift as content "
                        f"behind the focus plane does with A as the {a_view} view")
    else:
        evidence = f"A as the {a_view} view, as asked"
    left, right = (a_image, b_image) if a_view == "left" else (b_image, a_image)
    return DualPixelViews(left, right, combined, a_view, evidence, float(clipped.mean()),
                          _inverted_share(raw, clipped))


def _check_scale(scale: float) -> None:
    if not 0.0 < scale <= 1.0:
        raise ParameterError(f"scale must be in (0, 1], got {scale}")


def _resized(image: np.ndarray, scale: float) -> np.ndarray:
    if scale == 1.0:
        return image
    height, width = image.shape[:2]
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def import_dual_pixel_raws(
    paths: list[Path], output: str | Path, *, split: str = "test", a_view: str = "auto",
    suffix: str = ".png", progress: bool = False, scale: float = 1.0,
) -> list[tuple[Path, DualPixelViews]]:
    """Develop DPRAW files into a DPDD-layout folder (``{split}_l/source``, ``{split}_r/source``,
    ``{split}_c/source``; 16-bit, the file's orientation in EXIF), ready for ``dualpixel deblur
    --input``. Each file's three images are written atomically once it is developed; a bad file
    stops the import with an error naming it. Warns, naming the file, when over 0.1 % of a frame
    had clipped highlights (B estimated there) or A brighter than A+B (B black there), and when
    a frame is wider than twice :data:`MODEL_WIDTH` at ``scale`` 1. Returns each source with
    its views."""
    import warnings

    from dualpixel.io.atomic import check_writable
    from dualpixel.io.images import check_image_path, write_png
    from dualpixel.io.metadata import ImageMetadata
    from dualpixel.progress import progress_bar

    output = Path(output)
    names = [Path(p).stem for p in paths]
    if len(set(names)) < len(names):
        raise ParameterError("two raw files share a name; import them into separate folders")
    folders = {role: output / f"{split}_{role}" / "source" for role in ("l", "r", "c")}
    check_image_path(folders["l"] / f"probe{suffix}")
    _check_scale(scale)  # before any folder is made
    made = [f for folder in folders.values() for f in (folder, folder.parent, output)
            if not f.exists()]  # removed again, empty, if the import fails
    for folder in folders.values():
        check_writable(folder / f"probe{suffix}")
    results = []
    try:
        for path in progress_bar(paths, desc="developing", unit="file", enabled=progress):
            raw = read_dual_pixel_raw(path)  # one at a time: 30 MP frames are large
            views = develop_views(raw, a_view=a_view, scale=scale)
            width = raw.combined.shape[1]
            if scale == 1.0 and width > 2 * MODEL_WIDTH:
                warnings.warn(f"{path}: a {width}-px frame carries about "
                              f"{width / MODEL_WIDTH:.0f}x the blur the shipped models were "
                              f"trained on; import with --scale {MODEL_WIDTH / width:.2f} for "
                              "them", stacklevel=2)
            if views.clipped > 0.001:
                warnings.warn(f"{path}: {100 * views.clipped:.1f} % of the frame is clipped in "
                              "the combined exposure but not in A; the B view is estimated "
                              "from A there", stacklevel=2)
            if views.inverted > 0.001:
                warnings.warn(f"{path}: {100 * views.inverted:.1f} % of the frame has the A frame "
                              "brighter than the A+B frame, so the B view is black there: the "
                              "frames look swapped, or this is not a Dual Pixel RAW pair",
                              stacklevel=2)
            metadata = ImageMetadata.from_orientation(raw.orientation)
            for role, image in (("l", views.left), ("r", views.right), ("c", views.combined)):
                write_png(folders[role] / f"{Path(path).stem}{suffix}", image, bit_depth=16,
                          metadata=metadata)
            results.append((Path(path), views))
    except BaseException:
        for folder in sorted(set(made), key=lambda f: len(f.parts), reverse=True):
            with contextlib.suppress(OSError):  # kept where something was written
                folder.rmdir()
        raise
    return results
