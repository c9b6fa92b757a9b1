"""Issue #75: a folder of frames is one capture. A frame of another size, channel count or bit
depth mid-sequence is refused before any work, naming it; numbered frames that skip a number
are named in a warning; a sequence of one frame runs as a frame."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError
from dualpixel.inference.jobs import check_sequence_frames


def write_frames(folder, numbers, change=None):
    folder.mkdir(parents=True)
    rng = np.random.default_rng(0)
    paths = []
    for number in numbers:
        image = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
        if change is not None and number == 2:
            image = change(image)
        paths.append(folder / f"frame_{number:04d}.png")
        cv2.imwrite(str(paths[-1]), image)
    return paths


@pytest.mark.parametrize("change, said", [
    (lambda im: im[:, :56], "size 56x48 differs from the sequence's first frame frame_0000.png "
                            "(64x48)"),
    (lambda im: im[..., 0], "channels 1 channel(s) differs"),
    (lambda im: im.astype(np.uint16) * 257, "bit depth 16-bit differs"),
])
def test_a_frame_that_changes_mid_sequence_is_named(tmp_path, change, said):
    paths = write_frames(tmp_path / "left", range(4), change)
    with pytest.raises(InputFileError, match=r"frame_0002\.png: " + said.replace("(", r"\(")
                       .replace(")", r"\)")):
        check_sequence_frames(paths)
    write_frames(tmp_path / "right", range(4))
    result = CliRunner().invoke(cli, ["deblur", "--left", str(tmp_path / "left"), "--right",
                                      str(tmp_path / "right"), "-o", str(tmp_path / "out"),
                                      "--device", "cpu"])
    assert result.exit_code == 1 and "frame_0002.png" in result.output, result.output
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_gap_in_the_numbers_is_named_and_one_frame_runs_as_a_frame(tmp_path, tiny_checkpoint):
    paths = write_frames(tmp_path / "left", [0, 1, 3, 4])
    with pytest.warns(UserWarning, match=r"frame_0003\.png: the frames skip from number 1 to 3"):
        check_sequence_frames(paths)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_sequence_frames(paths[:2])  # consecutive: nothing said
    one = write_frames(tmp_path / "one", [7])
    write_frames(tmp_path / "one_right", [7])
    result = CliRunner().invoke(cli, ["deblur", "--left", str(tmp_path / "one"), "--right",
                                      str(tmp_path / "one_right"), "-o", str(tmp_path / "o1"),
                                      "--checkpoint", str(tiny_checkpoint), "--device", "cpu"])
    assert result.exit_code == 0, result.output
    alone = CliRunner().invoke(cli, ["deblur", "--left", str(one[0]), "--right",
                                     str(tmp_path / "one_right" / one[0].name), "-o",
                                     str(tmp_path / "alone.png"), "--checkpoint",
                                     str(tiny_checkpoint), "--device", "cpu"])
    assert alone.exit_code == 0, alone.output
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "o1" / one[0].name)),
                                  cv2.imread(str(tmp_path / "alone.png")))


def test_image_layout_reads_what_read_view_reads(tmp_path):
    """The header-only layout agrees with decoding the file, for each format written here."""
    import tifffile

    from dualpixel.io.images import image_layout, read_view

    rng = np.random.default_rng(1)
    cases = {"grey16.png": rng.integers(0, 65535, (20, 30), dtype=np.uint16),
             "rgb8.png": rng.integers(0, 255, (20, 30, 3), dtype=np.uint8),
             "rgba8.png": rng.integers(0, 255, (20, 30, 4), dtype=np.uint8),
             "rgb8.jpg": rng.integers(0, 255, (20, 30, 3), dtype=np.uint8),
             "grey8.jpg": rng.integers(0, 255, (20, 30), dtype=np.uint8)}
    for name, data in cases.items():
        cv2.imwrite(str(tmp_path / name), data)
    tifffile.imwrite(tmp_path / "rgb16.tif", rng.integers(0, 65535, (20, 30, 3), np.uint16),
                     photometric="rgb")
    tifffile.imwrite(tmp_path / "grey8.tif", rng.integers(0, 255, (20, 30), np.uint8))
    for path in sorted(tmp_path.iterdir()):
        image, bits = read_view(path)
        assert image_layout(path) == (*image.shape, bits), path.name
