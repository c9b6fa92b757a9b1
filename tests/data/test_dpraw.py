"""Dual Pixel RAW import: the A/B arithmetic recovers known views, the left view is told by
measurement, and files that are not DPRAW are refused by name."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import tifffile
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.data.dpraw import DualPixelRaw, develop_views, split_dual_pixel
from dualpixel.errors import InputFileError, ParameterError

BLACK, WHITE = 512.0, 15000.0


def _linear(srgb: np.ndarray) -> np.ndarray:
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def _mosaic(rgb: np.ndarray) -> np.ndarray:
    """RGGB samples of an ``(H, W, 3)`` image."""
    out = rgb[..., 1].copy()
    out[0::2, 0::2], out[1::2, 1::2] = rgb[0::2, 0::2, 0], rgb[1::2, 1::2, 2]
    return out


@pytest.fixture(scope="module")
def scene(behind_focus_frame):
    """Known left/right views (synthetic; background behind the focus plane)."""
    return behind_focus_frame


def _raw_of(left: np.ndarray, right: np.ndarray) -> DualPixelRaw:
    """What a DPRAW stores for views ``left`` (= A) and ``right`` (= B): sensor counts of A+B and
    of A, each view half the light, under a white balance of (2, 1, 1.5)."""
    balance = np.array([2.0, 1.0, 1.5])
    a_only = _mosaic(_linear(left) / balance) / 2
    b_only = _mosaic(_linear(right) / balance) / 2
    counts = lambda x: np.rint(BLACK + x * (WHITE - BLACK)).astype(np.uint16)  # noqa: E731
    return DualPixelRaw(counts(a_only + b_only), counts(a_only), "RGGB",
                        np.full((2, 2), BLACK), WHITE, (2.0, 1.0, 1.5))


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1 / np.mean((a[4:-4, 4:-4] - b[4:-4, 4:-4]) ** 2)))


def test_split_recovers_each_views_light(scene):
    raw = _raw_of(scene["left"], scene["right"])
    a_view, b_view, combined = split_dual_pixel(raw)
    balance = np.array([2.0, 1.0, 1.5])
    for view, known in ((a_view, scene["left"]), (b_view, scene["right"])):
        assert np.abs(view - _mosaic(_linear(known) / balance)).max() < 3 / (WHITE - BLACK)
    assert np.allclose(combined, (a_view + b_view) / 2, atol=2 / (WHITE - BLACK))


@pytest.mark.parametrize("a_is", ["left", "right"])
def test_develop_tells_the_left_view_by_measurement(scene, a_is):
    left, right = scene["left"], scene["right"]
    raw = _raw_of(left, right) if a_is == "left" else _raw_of(right, left)
    views = develop_views(raw)
    assert views.a_view == a_is and "defocused regions" in views.evidence
    assert _psnr(views.left, left) > 30 and _psnr(views.right, right) > 30  # demosaicing
    assert _psnr(views.combined, scene["combined"]) > 30
    forced = develop_views(raw, a_view="left")
    assert forced.a_view == "left" and np.array_equal(forced.left, views.left if a_is == "left"
                                                      else views.right)


def _dng(path, frames: int, orientation: int = 6) -> None:
    """A minimal DNG of ``frames`` raw images, one per IFD: LibRaw counts them but gives the
    first for every ``shot_select`` (a second frame it reads only as a second sample per pixel,
    :func:`_two_frame_dng`)."""
    cfa = np.random.default_rng(0).integers(600, 14000, (64, 96)).astype(np.uint16)
    colour = (10000, 10000, 0, 10000, 0, 10000, 0, 10000, 10000, 10000, 0, 10000, 0, 10000, 0,
              10000, 10000, 10000)
    with tifffile.TiffWriter(path) as tiff:
        tiff.write(np.zeros((8, 12, 3), np.uint8), photometric="rgb", subfiletype=1,
                   subifds=frames, metadata=None, extratags=[
                       (50706, "B", 4, (1, 4, 0, 0), True), (50708, "s", 0, "Test DP", True),
                       (50721, "2i", 9, colour, True), (50728, "2I", 3, (1, 2, 1, 1, 1, 2), True),
                       (274, "H", 1, orientation, True)])
        for _ in range(frames):
            tiff.write(cfa, photometric=32803, subfiletype=0, metadata=None, extratags=[
                (33421, "H", 2, (2, 2), True), (33422, "B", 4, (0, 1, 1, 2), True),
                (50714, "H", 1, int(BLACK), True), (50717, "H", 1, int(WHITE), True)])


def test_one_frame_raw_and_junk_are_refused(tmp_path):
    pytest.importorskip("rawpy")
    from dualpixel.data.dpraw import read_dual_pixel_raw

    _dng(tmp_path / "single.dng", 1)
    with pytest.raises(InputFileError, match=r"single\.dng.*one raw frame"):
        read_dual_pixel_raw(tmp_path / "single.dng")
    _dng(tmp_path / "same.dng", 2)  # LibRaw gives the first frame twice: still one frame
    with pytest.raises(InputFileError, match="one raw frame"):
        read_dual_pixel_raw(tmp_path / "same.dng")
    (tmp_path / "junk.CR2").write_bytes(b"II*\x00 not really a raw file")
    result = CliRunner().invoke(cli, ["import-dpraw", str(tmp_path / "junk.CR2"),
                                      "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and "junk.CR2" in result.output
    assert "camera raw" in result.output and "Traceback" not in result.output
    assert "b'" not in result.output  # LibRaw's message as text, not a bytes repr
    assert not (tmp_path / "out").exists()  # a failed import leaves no empty folders


#: Linear sRGB from CIE XYZ (D65): as a DNG's ColorMatrix1 it makes camera RGB linear sRGB.
SRGB_FROM_XYZ = np.linalg.inv([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169],
                               [0.019334, 0.119193, 0.950227]])


def _two_frame_dng(path, raw: DualPixelRaw, colour_matrix, orientation: int = 1,
                   white: float = WHITE) -> None:
    """A DNG holding a Dual Pixel RAW's two frames as LibRaw reads two frames of a DNG: one CFA
    image of two samples per pixel (A+B, then A; the layout of Fuji's two-frame DNGs), whose
    ``shot_select=1`` is the second. ``colour_matrix`` (XYZ -> camera, 3x3) and the white
    balance of ``raw`` go into the file's tags. tifffile writes no multi-sample CFA image, so
    it is written grey and its photometric tag rewritten to CFA in place."""
    neutral = [v for w in raw.white_balance for v in (10000, round(10000 * w))]
    matrix = [v for m in np.ravel(colour_matrix) for v in (round(10000 * m), 10000)]
    with tifffile.TiffWriter(path) as tiff:
        tiff.write(np.zeros((8, 12, 3), np.uint8), photometric="rgb", subfiletype=1, subifds=1,
                   metadata=None, extratags=[
                       (50706, "B", 4, (1, 4, 0, 0), True), (50708, "s", 0, "Test DP", True),
                       (50721, "2i", 9, matrix, True), (50728, "2I", 3, neutral, True),
                       (274, "H", 1, orientation, True)])
        tiff.write(np.stack((raw.combined, raw.a_only), axis=-1), photometric="minisblack",
                   planarconfig="contig", extrasamples=[0], subfiletype=0, metadata=None,
                   extratags=[(33421, "H", 2, (2, 2), True), (33422, "B", 4, (0, 1, 1, 2), True),
                              (50714, "H", 1, int(BLACK), True),
                              (50717, "H", 1, int(white), True)])
    with tifffile.TiffFile(path, mode="r+b") as tiff:
        tiff.filehandle.seek(tiff.pages[0].tags["SubIFDs"].value[0])
        tifffile.TiffPage(tiff, index=1).tags["PhotometricInterpretation"].overwrite(32803)


def test_two_frame_dng_through_the_import_path(scene, tmp_path):
    """A two-frame raw file written by a library (no stand-in module) is read by LibRaw, split
    and developed back into the known views, its orientation and white balance read."""
    pytest.importorskip("rawpy")
    from dualpixel.data import dpraw

    stored = _raw_of(scene["left"], scene["right"])
    _two_frame_dng(tmp_path / "IMG_0001.dng", stored, SRGB_FROM_XYZ, orientation=6)
    raw = dpraw.read_dual_pixel_raw(tmp_path / "IMG_0001.dng")
    assert raw.pattern == "RGGB" and raw.orientation == 6
    assert raw.white_balance == pytest.approx((2.0, 1.0, 1.5), rel=1e-3)
    np.testing.assert_allclose(raw.colour_matrix, np.eye(3), atol=2e-3)  # camera RGB is sRGB
    np.testing.assert_array_equal(raw.combined, stored.combined)
    np.testing.assert_array_equal(raw.a_only, stored.a_only)
    [(_, views)] = dpraw.import_dual_pixel_raws([tmp_path / "IMG_0001.dng"], tmp_path / "dp")
    assert views.a_view == "left"
    assert _psnr(views.left, scene["left"]) > 30 and _psnr(views.right, scene["right"]) > 30


def test_a_dng_whose_white_level_is_below_its_black_level_is_named(scene, tmp_path):
    """Issue #72: damaged levels are the file's fault, and the message says which file."""
    pytest.importorskip("rawpy")
    stored = _raw_of(scene["left"], scene["right"])
    _two_frame_dng(tmp_path / "IMG_0002.dng", stored, SRGB_FROM_XYZ, white=300)
    result = CliRunner().invoke(cli, ["import-dpraw", str(tmp_path / "IMG_0002.dng"),
                                      "--output", str(tmp_path / "dp")])
    assert result.exit_code == 1, result.output
    assert "IMG_0002.dng: its white level 300 is not above its black level 512" in result.output


def test_import_dpraw_develops_a_real_file_as_libraw_flags_clipping_and_scales(tmp_path):
    """`import-dpraw` on a two-frame DNG of flat patches under the 5D Mark IV's colour matrix:
    the combined view holds the colours LibRaw's own development gives the A+B frame, the rows
    where the sum clipped and A did not are flagged, and --scale halves the views."""
    rawpy = pytest.importorskip("rawpy")
    import cv2

    from dualpixel.io.images import read_rgb

    rng = np.random.default_rng(1)
    full = np.kron(rng.uniform(0.05, 0.45, (6, 8, 3)), np.ones((16, 16, 1)))
    counts = lambda x: np.rint(BLACK + _mosaic(x) * (WHITE - BLACK)).astype(np.uint16)  # noqa: E731
    combined = counts(full)
    combined[:8] = WHITE  # the sum clipped in the top rows, A (half the light) not
    capture = DualPixelRaw(combined, counts(full / 2), "RGGB", np.full((2, 2), BLACK), WHITE,
                           (2.0, 1.0, 2.0))
    xyz_to_camera = np.reshape(EOS_5D4, (3, 3)) / 1e4
    path = tmp_path / "patches.dng"
    _two_frame_dng(path, capture, xyz_to_camera)
    result = CliRunner().invoke(cli, ["import-dpraw", str(path), "-o", str(tmp_path / "dp"),
                                      "--a-view", "left", "--scale", "0.5"])
    assert result.exit_code == 0, result.output
    assert "patches.dng" in result.output and "clipped" in result.output
    views = {role: _linear(read_rgb(tmp_path / "dp" / f"test_{role}" / "source" /
                                      "patches.png")) for role in "lrc"}
    assert all(v.shape == (48, 64, 3) for v in views.values())  # --scale 0.5 of 96x128
    with rawpy.imread(str(path)) as raw:
        reference = raw.postprocess(
            use_camera_wb=True, no_auto_bright=True, gamma=(1, 1), output_bps=16, user_flip=0,
            output_color=rawpy.ColorSpace.sRGB, highlight_mode=rawpy.HighlightMode.Clip,
            demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR) / 65535.0
    reference = cv2.resize(reference, (64, 48), interpolation=cv2.INTER_AREA)
    patches = lambda image: image.reshape(6, 8, 8, 8, 3)[1:, 2:-2, :, 2:-2].mean(axis=(1, 3))  # noqa: E731
    assert np.abs(patches(views["c"]) - patches(reference)).max() < 2e-3  # below the clip
    assert np.abs(patches(views["l"]) - patches(views["r"])).max() < 2e-3  # A and B alike


def test_missing_rawpy_names_the_extra(tmp_path, monkeypatch):
    from dualpixel.data.dpraw import read_dual_pixel_raw

    monkeypatch.setitem(sys.modules, "rawpy", None)
    with pytest.raises(ParameterError, match=r"dualpixel\[raw\]"):
        read_dual_pixel_raw(tmp_path / "x.CR2")


def test_import_writes_a_dpdd_folder_deblur_reads(scene, tmp_path, monkeypatch):
    import dualpixel.data.dpraw as dpraw
    from dualpixel.io.metadata import read_metadata

    raws = {"one": _raw_of(scene["left"], scene["right"])}
    raws["two"] = DualPixelRaw(**{**vars(raws["one"]), "orientation": 8})
    monkeypatch.setattr(dpraw, "read_dual_pixel_raw", lambda path: raws[path.stem])
    results = dpraw.import_dual_pixel_raws([tmp_path / "one.CR2", tmp_path / "two.CR2"],
                                           tmp_path / "dp")
    assert [views.a_view for _, views in results] == ["left", "left"]
    for role in ("l", "r", "c"):
        assert sorted(p.name for p in (tmp_path / "dp" / f"test_{role}" / "source").iterdir()) \
            == ["one.png", "two.png"]
    assert read_metadata(tmp_path / "dp" / "test_l" / "source" / "two.png").orientation == 8
    from dualpixel.data.layout import discover_dp_dataset

    pairs = discover_dp_dataset(tmp_path / "dp", "test", require_target=False)
    assert len(pairs) == 2 and all(p.frames[0].combined is not None for p in pairs)


def test_clipped_highlights_take_b_from_a_and_are_flagged(scene):
    raw = _raw_of(scene["left"], scene["right"])
    combined = raw.combined.copy()
    combined[:8, :] = WHITE  # the sum clipped in the top rows, A not
    clipped = DualPixelRaw(**{**vars(raw), "combined": combined})
    a_view, b_view, _ = split_dual_pixel(clipped)
    np.testing.assert_array_equal(b_view[:8], a_view[:8])  # estimated from A, not (W - A)
    views = develop_views(clipped, a_view="left")
    assert views.clipped == pytest.approx(8 / raw.combined.shape[0], rel=0.05)
    assert develop_views(raw, a_view="left").clipped == 0.0


def test_import_scales_down_and_warns_on_clipping_and_on_full_size_frames(scene, tmp_path,
                                                                          monkeypatch):
    import dualpixel.data.dpraw as dpraw

    raw = _raw_of(scene["left"], scene["right"])
    combined = raw.combined.copy()
    combined[:8, :] = WHITE
    clipped = DualPixelRaw(**{**vars(raw), "combined": combined})
    monkeypatch.setattr(dpraw, "read_dual_pixel_raw", lambda path: clipped)
    with pytest.warns(UserWarning, match=r"one\.CR2: .* % of the frame is clipped"):
        [(_, views)] = dpraw.import_dual_pixel_raws([tmp_path / "one.CR2"], tmp_path / "dp",
                                                    scale=0.5, a_view="left")
    height, width = scene["left"].shape[:2]
    assert views.left.shape == (height // 2, width // 2, 3)
    full = np.tile(raw.combined, (1, 40))  # a frame wider than twice the training width
    wide = DualPixelRaw(**{**vars(raw), "combined": full, "a_only": np.tile(raw.a_only, (1, 40))})
    monkeypatch.setattr(dpraw, "read_dual_pixel_raw", lambda path: wide)
    monkeypatch.setattr(dpraw, "develop_views", lambda *a, **k: views)  # the size alone matters
    with pytest.warns(UserWarning, match=r"wide\.CR2: a \d+-px frame carries about .* --scale"):
        dpraw.import_dual_pixel_raws([tmp_path / "wide.CR2"], tmp_path / "dp2", a_view="left")
    with pytest.raises(ParameterError, match="scale must be in"):
        dpraw.import_dual_pixel_raws([tmp_path / "x.CR2"], tmp_path / "dp3", scale=0.0)
    assert not (tmp_path / "dp3").exists()


#: The Canon EOS 5D Mark IV's XYZ -> camera matrix (dcraw's table, x 10000).
EOS_5D4 = (6446, -366, -864, -4436, 12204, 2513, -952, 2496, 6348)


def _patch_dng(path, patch: int = 16) -> None:
    """A DNG of flat camera-RGB patches (RGGB, black 512, white 15000) with the 5D Mark IV's
    colour matrix and an as-shot neutral of (0.5, 1, 0.5), i.e. a white balance of (2, 1, 2)."""
    rng = np.random.default_rng(1)
    full = np.kron(rng.uniform(0.05, 0.45, (6, 8, 3)), np.ones((patch, patch, 1)))
    counts = np.rint(BLACK + _mosaic(full) * (WHITE - BLACK)).astype(np.uint16)
    colour = tuple(v for m in EOS_5D4 for v in (m, 10000))
    with tifffile.TiffWriter(path) as tiff:
        tiff.write(np.zeros((8, 12, 3), np.uint8), photometric="rgb", subfiletype=1, subifds=1,
                   metadata=None, extratags=[
                       (50706, "B", 4, (1, 4, 0, 0), True), (50708, "s", 0, "Test DP", True),
                       (50721, "2i", 9, colour, True), (50728, "2I", 3, (1, 2, 1, 1, 1, 2), True),
                       (274, "H", 1, 1, True)])
        tiff.write(counts, photometric=32803, subfiletype=0, metadata=None, extratags=[
            (33421, "H", 2, (2, 2), True), (33422, "B", 4, (0, 1, 1, 2), True),
            (50714, "H", 1, int(BLACK), True), (50717, "H", 1, int(WHITE), True)])


def test_colour_matrix_develops_as_libraw(tmp_path):
    """A raw frame developed here (white balance, demosaic, the camera's colour matrix) holds
    the colours LibRaw's own development gives it (rawpy's postprocess, linear sRGB)."""
    import dataclasses
    import types

    rawpy = pytest.importorskip("rawpy")
    from dualpixel.data.dpraw import camera_colour_matrix

    _patch_dng(tmp_path / "patches.dng")
    with rawpy.imread(str(tmp_path / "patches.dng")) as raw:
        frame = raw.raw_image_visible.copy()
        matrix = camera_colour_matrix(raw)
        reference = raw.postprocess(
            use_camera_wb=True, no_auto_bright=True, gamma=(1, 1), output_bps=16, user_flip=0,
            output_color=rawpy.ColorSpace.sRGB, highlight_mode=rawpy.HighlightMode.Clip,
            demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR) / 65535.0
    # the frame as the combined image of a capture whose two halves saw the same light
    half = np.rint(BLACK + (frame - BLACK) / 2.0).astype(np.uint16)
    capture = DualPixelRaw(frame, half, "RGGB", np.full((2, 2), BLACK), WHITE, (2.0, 1.0, 2.0),
                           colour_matrix=matrix)
    patches = lambda image: image.reshape(6, 16, 8, 16, 3)[:, 4:-4, :, 4:-4].mean(axis=(1, 3))  # noqa: E731
    ours = patches(_linear(develop_views(capture, a_view="left").combined))
    assert np.abs(ours - patches(reference)).max() < 1e-3
    plain = patches(_linear(develop_views(dataclasses.replace(capture, colour_matrix=None),
                                          a_view="left").combined))
    assert np.abs(plain - patches(reference)).mean() > 0.02  # the matrix is what matches
    # a file that gives only the XYZ -> camera matrix: the same matrix, by dcraw's rule
    xyz_only = types.SimpleNamespace(color_matrix=np.zeros((3, 4)),
                                     rgb_xyz_matrix=np.vstack((np.reshape(EOS_5D4, (3, 3)) / 1e4,
                                                               np.zeros((1, 3)))))
    np.testing.assert_allclose(camera_colour_matrix(xyz_only), matrix, atol=1e-4)
    assert camera_colour_matrix(types.SimpleNamespace()) is None  # none given: none applied


def test_a_frame_brighter_than_the_sum_is_measured_and_warned(scene, tmp_path, monkeypatch):
    """Issue #72: frames stored the other way round (A+B second) give B = 0 wherever A is
    brighter: the import says so, naming the file; a true pair has no such site."""
    import dualpixel.data.dpraw as dpraw

    raw = _raw_of(scene["left"], scene["right"])
    assert develop_views(raw, a_view="left").inverted == 0.0
    swapped = DualPixelRaw(**{**vars(raw), "combined": raw.a_only, "a_only": raw.combined})
    views = develop_views(swapped, a_view="left")
    assert views.inverted > 0.3
    assert float(np.mean(views.right == 0.0)) > 0.3  # what the user would otherwise get
    monkeypatch.setattr(dpraw, "read_dual_pixel_raw", lambda path: swapped)
    with pytest.warns(UserWarning, match=r"two\.CR2: .* % of the frame has the A frame brighter "
                                         r"than the A\+B frame"):
        dpraw.import_dual_pixel_raws([tmp_path / "two.CR2"], tmp_path / "dp", a_view="left")
    monkeypatch.setattr(dpraw, "read_dual_pixel_raw", lambda path: raw)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dpraw.import_dual_pixel_raws([tmp_path / "one.CR2"], tmp_path / "dp1", a_view="left")
