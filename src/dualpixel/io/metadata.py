"""What a photograph carries besides its pixels: the ICC colour profile and EXIF.

Reading pixels ignores EXIF orientation (DP disparity lives in sensor coordinates, so the views
must stay as the sensor saw them); writing an output puts the input's profile and EXIF back, so a
portrait still displays upright and colour-managed viewers read the colours as the camera meant.

What each output format keeps:

- PNG: the ICC profile (``iCCP``) and the whole EXIF (``eXIf``);
- JPEG: the ICC profile (``APP2``) and the whole EXIF (``APP1``; a maker note that would overflow
  the 64 KiB segment is left out);
- TIFF: the ICC profile and the descriptive first-IFD tags (orientation, make, model, date,
  software, artist, copyright, description), not the EXIF exposure sub-IFD;
- BMP: nothing (the format has no place for it).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ImageMetadata", "embed_metadata", "read_metadata", "tiff_write_options"]

#: First-IFD tags that describe the photograph (not its pixel layout): ImageDescription, Make,
#: Model, Orientation, Software, DateTime, Artist, Copyright.
DESCRIPTIVE_TAGS = (270, 271, 272, 274, 305, 306, 315, 33432)
ORIENTATION_TAG = 274
_SUB_IFDS = (0x8769, 0x8825)  # the EXIF and GPS sub-IFDs
_MAKER_NOTE = 0x927C
_EXIF_PREFIX = b"Exif\x00\x00"
_JPEG_SEGMENT_MAX = 65533  # payload bytes of one APPn segment (its length field counts itself)
_ICC_CHUNK = 65519  # payload of one APP2 ICC segment after its 14-byte header


@dataclass(frozen=True)
class ImageMetadata:
    """An image's ICC profile and EXIF (``Exif\\0\\0`` + TIFF-structured bytes), either absent."""

    icc_profile: bytes | None = None
    exif: bytes | None = None

    @classmethod
    def from_orientation(cls, orientation: int) -> ImageMetadata:
        """Metadata that says only how to display the image (EXIF orientation 1-8)."""
        from PIL import Image

        exif = Image.Exif()
        exif[ORIENTATION_TAG] = int(orientation)
        return cls(exif=exif.tobytes())

    def __bool__(self) -> bool:
        return bool(self.icc_profile or self.exif)

    def tags(self) -> dict[int, object]:
        """The first-IFD EXIF tags, ``{tag: value}`` (empty without EXIF)."""
        return dict(_exif(self.exif)) if self.exif else {}

    @property
    def orientation(self) -> int:
        """EXIF orientation, 1 (upright) to 8; 1 when there is none."""
        value = self.tags().get(ORIENTATION_TAG, 1)
        return int(value) if isinstance(value, int) and 1 <= value <= 8 else 1


def _exif(data: bytes):
    from PIL import Image

    exif = Image.Exif()
    exif.load(data)
    return exif


def _descriptive_exif(exif, *, maker_note: bool = True) -> bytes | None:
    """A fresh EXIF with the descriptive first-IFD tags and the EXIF/GPS sub-IFDs of ``exif``
    (pixel-layout tags such as strip offsets and the thumbnail are dropped)."""
    from PIL import Image

    kept = Image.Exif()
    for tag in DESCRIPTIVE_TAGS:
        if tag in exif:
            kept[tag] = exif[tag]
    for pointer in _SUB_IFDS:
        ifd = dict(exif.get_ifd(pointer))
        if not maker_note:
            ifd.pop(_MAKER_NOTE, None)
        if ifd:
            kept[pointer] = ifd
    return kept.tobytes() if len(kept) else None


def read_metadata(path: str | Path) -> ImageMetadata:
    """The ICC profile and EXIF of an image file (from its header; pixels are not decoded).

    A file PIL cannot parse, or one without either, gives an empty :class:`ImageMetadata`:
    metadata is carried when present, never required.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            icc = image.info.get("icc_profile") or None
            if image.format == "PNG" and "exif" not in image.info:  # PIL would decode the
                found = _png_exif_after_pixels(path)  # pixels to look for one after them
                exif = _descriptive_exif(_exif(found)) if found else None
            else:
                exif = _descriptive_exif(image.getexif())
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        return ImageMetadata()
    return ImageMetadata(icc_profile=icc, exif=exif)


def _png_exif_after_pixels(path: str | Path) -> bytes | None:
    """The EXIF of a PNG's ``eXIf`` chunk (``Exif\\0\\0`` + its bytes), walking the chunks'
    headers without reading their data; None without one."""
    with open(path, "rb") as file:
        file.seek(8)  # the signature
        while header := file.read(8):
            if len(header) < 8:
                return None
            length, kind = struct.unpack(">I4s", header)
            if kind == b"eXIf":
                data = file.read(length)
                return _EXIF_PREFIX + data if len(data) == length else None
            if kind == b"IEND":
                return None
            file.seek(length + 4, 1)  # the data and its CRC
    return None


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _embed_png(encoded: bytes, metadata: ImageMetadata) -> bytes:
    chunks = b""
    if metadata.icc_profile:
        chunks += _png_chunk(b"iCCP", b"ICC profile\x00\x00" + zlib.compress(metadata.icc_profile))
    if metadata.exif:
        chunks += _png_chunk(b"eXIf", metadata.exif.removeprefix(_EXIF_PREFIX))
    ihdr_end = 8 + 8 + struct.unpack(">I", encoded[8:12])[0] + 4  # signature, IHDR
    return encoded[:ihdr_end] + chunks + encoded[ihdr_end:]


def _jpeg_segment(marker: int, payload: bytes) -> bytes:
    return struct.pack(">BBH", 0xFF, marker, len(payload) + 2) + payload


def _embed_jpeg(encoded: bytes, metadata: ImageMetadata) -> bytes:
    segments = b""
    if metadata.exif:
        exif = metadata.exif
        if len(exif) > _JPEG_SEGMENT_MAX:
            exif = _descriptive_exif(_exif(exif), maker_note=False) or b""
        if 0 < len(exif) <= _JPEG_SEGMENT_MAX:
            segments += _jpeg_segment(0xE1, exif)
    if metadata.icc_profile:
        icc = metadata.icc_profile
        parts = [icc[i : i + _ICC_CHUNK] for i in range(0, len(icc), _ICC_CHUNK)]
        if len(parts) <= 255:
            for number, part in enumerate(parts, 1):
                segments += _jpeg_segment(0xE2, b"ICC_PROFILE\x00" + bytes([number, len(parts)])
                                          + part)
    position = 2  # after SOI, and after the JFIF APP0 OpenCV writes first
    if encoded[2:4] == b"\xff\xe0":
        position += 2 + struct.unpack(">H", encoded[4:6])[0]
    return encoded[:position] + segments + encoded[position:]


def tiff_write_options(metadata: ImageMetadata) -> dict[str, object]:
    """Keyword arguments for ``tifffile.imwrite`` that store the profile and the descriptive
    first-IFD tags (and no tifffile description or software tag of its own)."""
    found = metadata.tags()
    text = {key: value if isinstance(value, str) and value.isascii() else None
            for key, value in (("description", found.get(270)), ("software", found.get(305)))}
    tags: list[tuple] = []
    if metadata.icc_profile:
        tags.append((34675, "B", len(metadata.icc_profile), metadata.icc_profile, True))
    for tag, value in sorted(found.items()):
        if tag not in DESCRIPTIVE_TAGS or tag in (270, 305):  # those two have keywords
            continue
        if isinstance(value, int):
            tags.append((tag, "H", 1, value, True))
        elif isinstance(value, str) and value.isascii():
            tags.append((tag, "s", 0, value, True))
    return {"extratags": tags, "metadata": None, "description": text["description"],
            "software": text["software"] or False}


def embed_metadata(encoded: bytes, suffix: str, metadata: ImageMetadata) -> bytes:
    """``encoded`` (a PNG or JPEG file's bytes) with ``metadata`` added; other formats as given
    (TIFF: :func:`tiff_write_options`)."""
    if not metadata:
        return encoded
    suffix = suffix.lower()
    if suffix == ".png":
        return _embed_png(encoded, metadata)
    if suffix in (".jpg", ".jpeg"):
        return _embed_jpeg(encoded, metadata)
    return encoded

