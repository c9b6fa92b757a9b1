"""Reading and writing images and depth maps, with errors that name the file and the problem."""

from __future__ import annotations

import io
import os
import threading
from contextlib import contextmanager
from pathlib import Path

import numpy as np

# OpenCV reads OpenEXR only when this is set before it is imported.
os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import cv2

from dualpixel.errors import InputFileError, OutputFileError, ParameterError
from dualpixel.io.atomic import atomic_path
from dualpixel.io.metadata import ImageMetadata, embed_metadata, tiff_write_options

__all__ = [
    "WRITE_FORMATS",
    "check_depth_map",
    "check_image_path",
    "check_png_compression",
    "decode_synthia_depth",
    "image_size",
    "load_npy",
    "max_level",
    "numpy_load_problem",
    "quantise",
    "read_depth",
    "read_rgb",
    "read_rgb_with_depth",
    "read_synthia_depth",
    "read_view",
    "read_views",
    "write_png",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
DEPTH_SUFFIXES = (".png", ".npy", ".exr", ".tif", ".tiff")


#: Bytes per pixel a decode may take at its peak: the decoded RGB(A) at up to 16 bits and two
#: float32 RGB copies (channel order, unit range).
DECODE_BYTES_PER_PIXEL = 32
_HEADER_LOCK = threading.Lock()


def image_size(path: str | Path) -> tuple[int, int]:
    """``(H, W)`` from the file's header, without decoding its pixels (any size is reported:
    PIL's decompression-bomb refusal is the memory guard's job here, see :func:`_imread`)."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    with _HEADER_LOCK:  # PIL's pixel limit is a module global
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            with Image.open(path) as image:
                width, height = image.size
        except FileNotFoundError:
            raise InputFileError(path, "file not found") from None
        except (UnidentifiedImageError, OSError, ValueError):
            raise InputFileError(path, "cannot be read as an image (corrupt or unsupported "
                                       "format)") from None
        finally:
            Image.MAX_IMAGE_PIXELS = limit
    return height, width


def image_layout(path: str | Path) -> tuple[int, int, int, int]:
    """``(H, W, channels, bits)`` of an image file from its header, as :func:`read_view` would
    read it (channels 1 or 3, alpha not counted; bits 8 or 16), without decoding its pixels:
    PNG from its IHDR chunk, TIFF from its first page's tags, other formats 8-bit."""
    path = Path(path)
    height, width = image_size(path)
    suffix = path.suffix.lower()
    if suffix == ".png":
        with open(path, "rb") as handle:
            header = handle.read(26)
        bits, colour = header[24], header[25]  # IHDR: bit depth, colour type
        channels = 1 if colour in (0, 4) else 3  # grey (+ alpha) or RGB / palette (+ alpha)
        return height, width, channels, 16 if bits == 16 else 8
    if suffix in (".tif", ".tiff"):
        import tifffile

        with tifffile.TiffFile(path) as tiff:
            page = tiff.pages[0]
            samples = int(page.samplesperpixel) - len(page.extrasamples or ())
            return height, width, 1 if samples == 1 else 3, 16 if page.bitspersample > 8 else 8
    from PIL import Image

    with Image.open(path) as image:
        return height, width, 1 if image.mode in ("L", "LA", "I;16") else 3, 8


#: How a complete file of each format ends (PNG: the IEND chunk; JPEG: the EOI marker).
_FILE_ENDINGS = {".png": b"IEND\xaeB`\x82", ".jpg": b"\xff\xd9", ".jpeg": b"\xff\xd9"}


def _check_complete(path: Path) -> None:
    """Refuse a PNG or JPEG cut short (a copy or download that stopped): decoders fill the
    missing rows with grey and only print a warning."""
    ending = _FILE_ENDINGS.get(path.suffix.lower())
    if ending is None:
        return
    with open(path, "rb") as handle:
        handle.seek(0, 2)
        size = handle.tell()
        handle.seek(max(0, size - 4096))
        tail = handle.read().rstrip(b"\x00")  # some writers pad JPEGs with zeros
    if not tail.endswith(ending) and ending not in tail:
        raise InputFileError(path, "is truncated (the file ends before its image data does); "
                                   "copy or export it again")


def _check_decodable(path: Path) -> None:
    """Refuse, with the numbers, a file whose declared size cannot be decoded in the memory
    available (a decompression bomb, or a photo too large for this machine)."""
    from dualpixel.memory import GIB, available_memory

    try:
        height, width = image_size(path)
    except InputFileError:
        return  # a format PIL does not know (e.g. EXR): OpenCV decides
    needed, available = height * width * DECODE_BYTES_PER_PIXEL, available_memory()
    if needed > available:
        raise InputFileError(path, f"declares {width}x{height} pixels, which need about "
                                   f"{needed / GIB:.1f} GiB to decode, but only "
                                   f"{available / GIB:.1f} GiB is available")


@contextmanager
def _decoder_quiet():
    """OpenCV's own log silenced while a file decodes: a file it cannot read gets our error,
    which names it, not the decoder's internal message besides (restored after)."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


def _imread(path: Path, kind: str = "image") -> np.ndarray:
    """The file's pixels as OpenCV reads them; ``kind`` ("image" or "depth map") words errors."""
    if not path.is_file():
        raise InputFileError(path, "file not found")
    _check_decodable(path)
    try:
        with _decoder_quiet():
            if path.suffix.lower() in (".tif", ".tiff"):
                data = cv2.imdecode(_tiff_upright_bytes(path), cv2.IMREAD_UNCHANGED)
            else:  # IMREAD_UNCHANGED ignores EXIF orientation: pixels stay in sensor order
                data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error:
        data = None
    if data is None and path.suffix.lower() == ".exr" and not cv2.haveImageReader(str(path)):
        hint = "a .npy of metres" if kind == "depth map" else "a 16-bit PNG or TIFF"
        raise InputFileError(
            path, f"this OpenCV build cannot read OpenEXR; convert this {kind} to {hint}"
        )
    if data is None:
        article = "an" if kind[0] in "aeiou" else "a"
        raise InputFileError(path, f"cannot be decoded as {article} {kind} "
                                   "(corrupt or unsupported format)")
    _check_complete(path)  # decoded, but maybe with the missing rows filled in grey
    if kind == "image" and data.dtype not in (np.uint8, np.uint16):
        raise InputFileError(path, f"holds {data.dtype} samples; images must be 8- or 16-bit "
                                   "unsigned (save float or signed data as a 16-bit TIFF or PNG)")
    return data


def _tiff_upright_bytes(path: Path) -> np.ndarray:
    """The TIFF file's bytes with its first page's orientation tag set to 1 (OpenCV 5 fails to
    decode a TIFF whose orientation is not 1; we want the stored, sensor-order pixels anyway)."""
    import io

    import tifffile

    data = io.BytesIO(path.read_bytes())
    try:
        with tifffile.TiffFile(data) as tiff:  # a handle given is left open
            tag = tiff.pages.first.tags.get(274)
            if tag is not None and tag.value != 1:
                tag.overwrite(1)  # in the copy in memory; the file is not touched
    except (tifffile.TiffFileError, OSError, ValueError, IndexError, KeyError, TypeError):
        pass  # not a TIFF tifffile can parse: OpenCV decides
    return np.frombuffer(data.getvalue(), np.uint8)


def _unit_range(path: Path, data: np.ndarray) -> np.ndarray:
    if data.dtype == np.uint8:
        return data.astype(np.float32) / 255.0
    if data.dtype == np.uint16:
        return data.astype(np.float32) / 65535.0
    raise InputFileError(path, f"expected an 8- or 16-bit image, got dtype {data.dtype}")


def read_rgb(path: str | Path) -> np.ndarray:
    """Read an 8- or 16-bit RGB (or grey) image as float32 ``(H, W, 3)`` in [0, 1] (alpha
    dropped; grey copied to the three channels)."""
    return read_rgb_with_depth(path)[0]


def max_level(bits: int) -> float:
    """The largest level of a ``bits``-bit file (8 or 16), by which :func:`read_rgb` divided:
    a level given in the file's own units (a raw black level) over it is a fraction of 1."""
    return 65535.0 if bits == 16 else 255.0


def _bits(data: np.ndarray) -> int:
    return 16 if data.dtype == np.uint16 else 8


def _rgb(path: Path, data: np.ndarray) -> np.ndarray:
    """Decoded pixels (OpenCV's order) as float32 RGB ``(H, W, 3)`` in [0, 1]."""
    if data.ndim == 2:  # a grey image: the same value in R, G and B
        data = cv2.merge([data, data, data])
    if data.ndim != 3 or data.shape[2] not in (3, 4):
        shape = "x".join(map(str, data.shape))
        raise InputFileError(path, f"expected an RGB image with 3 channels, got shape {shape}")
    return _unit_range(path, cv2.cvtColor(data[:, :, :3], cv2.COLOR_BGR2RGB))


def read_rgb_with_depth(path: str | Path) -> tuple[np.ndarray, int]:
    """Like :func:`read_rgb`, also returning the file's bit depth (8 or 16)."""
    path = Path(path)
    data = _imread(path)
    return _rgb(path, data), _bits(data)


def read_view(path: str | Path) -> tuple[np.ndarray, int]:
    """A DP view as float32 ``(H, W, C)`` in [0, 1] with the file's channels kept (``C`` 1 for
    a grey view, such as a phone's green-only DP data, 3 for colour; alpha dropped) and its
    bit depth (8 or 16)."""
    path = Path(path)
    data = _imread(path)
    if data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    if data.ndim == 2:
        return _unit_range(path, data)[:, :, None], _bits(data)
    return _rgb(path, data), _bits(data)


def read_views(left: str | Path, right: str | Path
               ) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Both views of a pair (:func:`read_view`) and their bit depths; a clear error naming the
    right view when they differ in size or in channels (a grey view given with a colour one)."""
    (left_image, left_bits), (right_image, right_bits) = read_view(left), read_view(right)
    (height, width), (left_height, left_width) = right_image.shape[:2], left_image.shape[:2]
    if (height, width) != (left_height, left_width):
        raise InputFileError(right, f"size differs from {Path(left).name} ({width}x{height} vs "
                                    f"{left_width}x{left_height})")
    if left_image.shape[2] != right_image.shape[2]:
        kinds = {1: "grey (one channel)", 3: "colour (RGB)"}
        raise InputFileError(right, f"is {kinds[right_image.shape[2]]} but the left view {left} "
                             f"is {kinds[left_image.shape[2]]}: give both views of one capture")
    return left_image, right_image, (left_bits, right_bits)


def decode_synthia_depth(bgr: np.ndarray, *, max_depth: float = 250.0) -> np.ndarray:
    """SYNTHIA-SF depth in metres: 1000 (R + 256 G + 65536 B) / (2^24 - 1), clipped at max_depth.

    ``bgr`` is an 8-bit image as OpenCV reads it (B, G, R channel order).
    """
    values = bgr.astype(np.float64)
    red, green, blue = values[..., 2], values[..., 1], values[..., 0]
    depth = 1000.0 * (red + 256.0 * green + 65536.0 * blue) / (2**24 - 1)
    return np.minimum(depth, max_depth).astype(np.float32)


def read_synthia_depth(path: str | Path, *, max_depth: float = 250.0) -> np.ndarray:
    """Read a SYNTHIA-SF ``DepthLeft`` PNG as metres, float32 ``(H, W)``."""
    path = Path(path)
    data = _imread(path)
    if data.dtype != np.uint8 or data.ndim != 3 or data.shape[2] < 3:
        raise InputFileError(
            path, f"expected SYNTHIA's 8-bit RGB-encoded depth, got {data.dtype} {data.shape}"
        )
    return decode_synthia_depth(data[:, :, :3], max_depth=max_depth)


def read_depth(path: str | Path, *, png_scale: float = 0.001) -> np.ndarray:
    """Read a depth map as float32 ``(H, W)``: ``.npy`` (as stored), ``.exr``/float TIFF (as
    stored) or a 16-bit PNG times ``png_scale`` (default: millimetres to metres)."""
    path = Path(path)
    if path.suffix.lower() == ".npy":
        depth = load_npy(path)
    else:
        depth = _imread(path, "depth map")
        if path.suffix.lower() == ".png":
            if depth.dtype != np.uint16:
                raise InputFileError(
                    path, f"depth PNG must be 16-bit (one channel), got {depth.dtype}"
                )
            depth = depth.astype(np.float32) * png_scale
    try:
        return check_depth_map(depth)
    except ParameterError as error:
        raise InputFileError(path, str(error)) from None


def check_depth_map(depth: np.ndarray) -> np.ndarray:
    """A depth map in metres as float32 ``(H, W)`` (also from ``(H, W, 1)``, or ``(H, W, C)``
    whose channels are equal: a grey map stored as colour), or a :class:`ParameterError` saying
    what is wrong: not real numbers, channels that differ (an RGB-encoded depth, to decode
    first), NaN/inf, or values <= 0."""
    depth = np.asarray(depth)
    if not (np.issubdtype(depth.dtype, np.floating) or np.issubdtype(depth.dtype, np.integer)):
        raise ParameterError(f"depth must hold real numbers (metres), not {depth.dtype}")
    if depth.ndim == 3 and depth.shape[2] >= 1:
        if any(not np.array_equal(depth[:, :, 0], depth[:, :, c])
               for c in range(1, depth.shape[2])):
            raise ParameterError(f"depth has {depth.shape[2]} channels that differ; expected one "
                                 "channel of metres (decode an RGB-encoded depth first)")
        depth = depth[:, :, 0]
    if depth.ndim != 2:
        raise ParameterError(f"depth must be a single-channel map, got shape {depth.shape}")
    depth = depth.astype(np.float32)
    if not np.isfinite(depth).all():
        raise ParameterError(f"depth has {int((~np.isfinite(depth)).sum())} NaN/inf values")
    if (depth <= 0).any():
        raise ParameterError(
            f"depth has {int((depth <= 0).sum())} zero or negative values (must be > 0)"
        )
    return depth


def quantise(image: np.ndarray, bit_depth: int) -> np.ndarray:
    """Float values in [0, 1] (clipped) to the nearest integer level of ``bit_depth``: uint8 for
    8 bits, uint16 for 16 (in float32, so a value within 0.002 levels of a half level may round
    either way)."""
    if bit_depth not in (8, 16):
        raise ParameterError(f"bit_depth must be 8 or 16, got {bit_depth}")
    peak = 255 if bit_depth == 8 else 65535
    image = np.asarray(image)
    scaled = np.multiply(image, np.float32(peak), dtype=np.float32, order="C")
    # OpenCV's saturating conversion rounds half to even, as np.rint does, and clips below 0 in
    # the same pass; values far above the peak would overflow its rounding, so they go first
    np.minimum(scaled, peak, out=scaled)
    rows = scaled.reshape(scaled.shape[0] if scaled.ndim else 1, -1)  # one channel for OpenCV
    levels = cv2.multiply(rows, 1.0, dtype=cv2.CV_8U if bit_depth == 8 else cv2.CV_16U)
    return levels.reshape(image.shape)


#: Output formats by suffix, with the bit depths they store.
WRITE_FORMATS: dict[str, tuple[int, ...]] = {
    ".png": (8, 16), ".tif": (8, 16), ".tiff": (8, 16), ".jpg": (8,), ".jpeg": (8,), ".bmp": (8,),
}


def check_image_path(path: str | Path) -> Path:
    """Refuse an output image path whose suffix names no format we write (before any work)."""
    path = Path(path)
    if path.is_dir():
        raise OutputFileError(path, "is a folder; give an image file name")
    if path.suffix.lower() not in WRITE_FORMATS:
        raise OutputFileError(
            path, f"unknown image format {path.suffix or '(no suffix)'}; use one of "
            f"{', '.join(WRITE_FORMATS)}"
        )
    return path


def check_png_compression(level: int | None) -> int | None:
    """Refuse a PNG compression level outside 0-9 (None: OpenCV's fast default)."""
    if level is not None and (isinstance(level, bool) or level not in range(10)):
        raise ParameterError(f"png_compression must be an integer in 0-9, got {level!r}")
    return level


def write_png(path: str | Path, image: np.ndarray, *, bit_depth: int = 16,
              metadata: ImageMetadata | None = None, compression: int | None = None) -> None:
    """Write an RGB float image in [0, 1] ``(H, W, 3)`` (or integer levels of ``bit_depth``)
    atomically, as PNG or the format of the suffix (TIFF keeps 16 bits; JPEG and BMP store 8, so
    16-bit levels are rescaled, never clipped). ``metadata``: an ICC profile and EXIF to carry
    (e.g. the input photograph's, :func:`~dualpixel.io.metadata.read_metadata`); what each format
    keeps is listed in :mod:`dualpixel.io.metadata`. ``compression``: PNG only, the zlib level
    0 (stored without row filters: about 10x faster than the default, 20-30 % larger) to 9
    (smallest, slowest); None keeps OpenCV's default, a run-length strategy that encodes a
    16-bit 1920x1080 frame in about 0.2 s, 2.5x faster than level 1, at about its size."""
    path = check_image_path(path)
    if bit_depth not in (8, 16):
        raise ParameterError(f"bit_depth must be 8 or 16, got {bit_depth}")
    check_png_compression(compression)
    if np.issubdtype(image.dtype, np.floating):
        image = quantise(image, bit_depth)
    stored = bit_depth if bit_depth in WRITE_FORMATS[path.suffix.lower()] else 8
    if stored != bit_depth:  # 16-bit levels into an 8-bit format
        image = np.rint(np.asarray(image, dtype=np.float64) / 257.0).astype(np.int64)
    dtype = np.uint8 if stored == 8 else np.uint16
    data = image if image.dtype == dtype else np.clip(image, 0, np.iinfo(dtype).max).astype(dtype)
    metadata = metadata or ImageMetadata()
    suffix = path.suffix.lower()
    if suffix in (".tif", ".tiff"):
        import tifffile

        buffer = io.BytesIO()
        tifffile.imwrite(buffer, data, photometric="rgb" if data.ndim == 3 else "minisblack",
                         compression="zlib", **tiff_write_options(metadata))
        encoded = buffer.getvalue()
    else:
        params = ([cv2.IMWRITE_PNG_COMPRESSION, compression]
                  if suffix == ".png" and compression is not None else [])
        if params and compression == 0:  # stored blocks: row filters would only cost time
            params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
        ok, array = cv2.imencode(suffix, cv2.cvtColor(data, cv2.COLOR_RGB2BGR)
                                 if data.ndim == 3 else data, params)
        if not ok:
            raise OutputFileError(path, "could not be encoded")
        encoded = embed_metadata(array.tobytes(), suffix, metadata)
    with atomic_path(path) as tmp:  # encoded in memory: a full disk is an error naming path
        tmp.write_bytes(encoded)


def declared_array_bytes(path: str | Path) -> int:
    """Bytes the arrays of a ``.npy`` or ``.npz`` file declare in their headers (read without
    loading them); an unreadable header is an error naming the file."""
    import zipfile

    path = Path(path)

    def header_bytes(handle) -> int:
        version = np.lib.format.read_magic(handle)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)
        shape, _, dtype = read(handle)
        return int(np.prod(shape, dtype=object)) * dtype.itemsize

    try:
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as archive:
                total = 0
                for member in archive.namelist():
                    if member.endswith(".npy"):
                        with archive.open(member) as handle:
                            total += header_bytes(handle)
                return total
        with open(path, "rb") as handle:
            return header_bytes(handle)
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as error:
        raise InputFileError(path, f"cannot be read as NumPy arrays ({error})") from None


def check_array_file(path: str | Path, most: int | None = None) -> None:
    """Refuse, before loading, a ``.npy``/``.npz`` file whose arrays declare more than ``most``
    bytes, or more than the memory available."""
    from dualpixel.memory import available_memory, format_bytes

    needed = declared_array_bytes(path)
    available = available_memory()
    if most is not None and needed > most:
        raise InputFileError(path, f"declares arrays of {format_bytes(needed)}; a file of this "
                                   f"kind holds at most {format_bytes(most)}")
    if needed > available:
        raise InputFileError(path, f"declares arrays of {format_bytes(needed)}, more than the "
                                   f"{format_bytes(available)} of memory available")


def load_npy(path: str | Path) -> np.ndarray:
    """A ``.npy`` array (no pickles); a missing or unreadable file, or one that declares more
    than the memory available, is an error naming it."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "file not found")
    check_array_file(path)
    try:
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError) as error:
        raise InputFileError(path, numpy_load_problem(error)) from None


def numpy_load_problem(error: Exception) -> str:
    """What ``np.load(..., allow_pickle=False)``'s ``error`` says, for a user: NumPy's own text
    for a file without an array header suggests loading it unsafely, which we never do."""
    if "pickle" in str(error):
        return ("is not a plain NumPy array file (no .npy header, or Python objects, which are "
                "never loaded)")
    return f"cannot be read as a NumPy array ({error})"


def save_npy(path: str | Path, array: np.ndarray) -> None:
    """Save a NumPy array atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        np.save(handle, array)
