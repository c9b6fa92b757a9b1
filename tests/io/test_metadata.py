"""ICC profile and EXIF (orientation included) survive from input to output, in every format."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
import tifffile
from click.testing import CliRunner
from PIL import Image, ImageCms

from dualpixel.cli.main import cli
from dualpixel.io.images import read_rgb_with_depth, write_png
from dualpixel.io.metadata import ImageMetadata, read_metadata

ICC = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()


def _photo(path, pixels: np.ndarray, orientation: int = 6) -> None:
    """A camera-like file: EXIF with orientation, make, model and exposure; an ICC profile."""
    if path.suffix == ".tif":
        tifffile.imwrite(path, pixels, photometric="rgb", extratags=[
            (274, "H", 1, orientation, True), (271, "s", 0, "Canon", True),
            (34675, "B", len(ICC), ICC, True)])
        return
    exif = Image.Exif()
    exif[274], exif[271], exif[272] = orientation, "Canon", "EOS 5D Mark IV"
    exif[0x8769] = {33434: 0.01, 37386: 50.0}  # exposure time, focal length
    Image.fromarray(pixels).save(path, exif=exif, icc_profile=ICC)


@pytest.mark.parametrize("source", [".png", ".jpg", ".tif"])
@pytest.mark.parametrize("target", [".png", ".jpg", ".tif"])
def test_profile_and_orientation_survive(tmp_path, source, target):
    rows, cols = np.mgrid[0:20, 0:30]  # landscape, smooth (JPEG keeps it within a few levels)
    pixels = np.stack([rows * 12, cols * 8, rows + cols * 4], axis=-1).astype(np.uint8)
    _photo(tmp_path / f"in{source}", pixels)
    image, bits = read_rgb_with_depth(tmp_path / f"in{source}")
    assert image.shape == (20, 30, 3)  # sensor order: orientation is not applied on reading
    metadata = read_metadata(tmp_path / f"in{source}")
    assert metadata.orientation == 6 and metadata.icc_profile == ICC
    write_png(tmp_path / f"out{target}", image, bit_depth=bits, metadata=metadata)
    back = read_metadata(tmp_path / f"out{target}")
    assert back.icc_profile == ICC
    assert back.orientation == 6 and back.tags()[271] == "Canon"
    with Image.open(tmp_path / f"out{target}") as written:
        exposure = dict(written.getexif().get_ifd(0x8769))
    if source != ".tif" and target != ".tif":  # TIFF keeps first-IFD tags only
        assert exposure == {33434: 0.01, 37386: 50.0}
    again, _ = read_rgb_with_depth(tmp_path / f"out{target}")
    tolerance = 0.05 if ".jpg" in (source, target) else 0.0
    assert np.abs(again - image).max() <= tolerance


def test_rotated_16_bit_tiff_reads_in_sensor_order(tmp_path):
    """OpenCV alone cannot decode a TIFF whose orientation is not 1; we read it as stored."""
    pixels = np.random.default_rng(1).integers(0, 65536, (12, 17, 3), np.uint16)
    for orientation in (3, 6, 8):
        _photo(tmp_path / "in.tif", pixels, orientation)
        image, bits = read_rgb_with_depth(tmp_path / "in.tif")
        assert bits == 16 and np.array_equal(np.rint(image * 65535).astype(np.uint16), pixels)


def test_no_metadata_writes_none(tmp_path):
    write_png(tmp_path / "plain.png", np.zeros((4, 5, 3)), bit_depth=8)
    write_png(tmp_path / "plain.tif", np.zeros((4, 5, 3)), bit_depth=16)
    assert not read_metadata(tmp_path / "plain.png")
    assert read_metadata(tmp_path / "plain.tif") == ImageMetadata()
    (tmp_path / "junk.png").write_bytes(b"not an image")
    assert read_metadata(tmp_path / "junk.png") == ImageMetadata()


def test_deblur_command_keeps_the_left_views_metadata(tiny_checkpoint, tmp_path):
    pixels = np.random.default_rng(2).integers(0, 65536, (32, 48, 3), np.uint16)
    _photo(tmp_path / "left.tif", pixels, orientation=6)  # 16-bit, ICC, a portrait by EXIF
    _photo(tmp_path / "right.tif", pixels, orientation=6)
    for output in ("out.tif", "out.png"):
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(tmp_path / "left.tif"), "--right",
            str(tmp_path / "right.tif"), "-o", str(tmp_path / output), "--checkpoint",
            str(tiny_checkpoint), "--device", "cpu"])
        assert result.exit_code == 0, result.output
        out = read_metadata(tmp_path / output)
        assert out.orientation == 6 and out.icc_profile == ICC and out.tags()[271] == "Canon"
        image, bits = read_rgb_with_depth(tmp_path / output)
        assert bits == 16 and image.shape == (32, 48, 3)  # as the sensor saw it


def test_png_exif_after_the_pixels_is_read_without_decoding_them(tmp_path, monkeypatch):
    """libpng may write ``eXIf`` after ``IDAT``: it is found by walking the chunk headers, and
    no PNG's pixels are decoded to read its metadata (PIL's ``getexif`` would)."""
    from PIL import ImageFile

    Image.fromarray(np.zeros((40, 60, 3), np.uint8)).save(tmp_path / "plain.png")
    data = (tmp_path / "plain.png").read_bytes()
    exif = ImageMetadata.from_orientation(8).exif.removeprefix(b"Exif\x00\x00")
    chunk = (len(exif).to_bytes(4, "big") + b"eXIf" + exif
             + zlib.crc32(b"eXIf" + exif).to_bytes(4, "big"))
    end = data.rindex(b"IEND") - 4
    (tmp_path / "after.png").write_bytes(data[:end] + chunk + data[end:])
    assert data.index(b"IDAT") < (tmp_path / "after.png").read_bytes().index(b"eXIf")

    def no_decoding(self):
        raise AssertionError("pixels decoded to read metadata")

    monkeypatch.setattr(ImageFile.ImageFile, "load", no_decoding)
    assert read_metadata(tmp_path / "after.png").orientation == 8
    assert not read_metadata(tmp_path / "plain.png")
    _photo(tmp_path / "before.png", np.zeros((40, 60, 3), np.uint8), orientation=3)
    assert read_metadata(tmp_path / "before.png").orientation == 3
