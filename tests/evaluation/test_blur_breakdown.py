"""PSNR by blur size: errors pooled per |CoC| bin, checked against sums done by hand."""

import math

import numpy as np
import pytest

from dualpixel.errors import InputFileError
from dualpixel.evaluation.blur_breakdown import BlurBreakdown, read_defocus


def test_pooled_psnr_and_error_share_by_hand():
    target = np.full((4, 4, 3), 0.5)
    defocus = np.zeros((4, 4), np.float32)
    defocus[:, 2:] = -5.0  # sign ignored: 8 px in focus, 8 px in the 4-8 px bin
    blurred = target.copy()
    blurred[:, 2:] += 0.1  # error only where defocused
    breakdown = BlurBreakdown()
    breakdown.add(defocus, {"input": blurred, "model": target + 0.01}, target)
    # a second image doubles the pixels but keeps each bin's mean error
    breakdown.add(defocus, {"input": blurred, "model": target + 0.01}, target)
    rows = {row["bin"]: row for row in breakdown.table()}
    assert rows["0-1 px"]["pixel_fraction"] == 0.5 and rows["4-8 px"]["pixel_fraction"] == 0.5
    assert rows["0-1 px"]["psnr"]["input"] is None  # no error at all
    assert rows["4-8 px"]["psnr"]["input"] == pytest.approx(20.0)
    assert rows["0-1 px"]["psnr"]["model"] == pytest.approx(40.0)
    assert rows["4-8 px"]["error_share"]["input"] == pytest.approx(1.0)
    assert rows["4-8 px"]["error_share"]["model"] == pytest.approx(0.5)
    assert rows["2-4 px"]["psnr"]["model"] is None and rows["2-4 px"]["pixel_fraction"] == 0
    assert math.isclose(sum(r["pixel_fraction"] for r in rows.values()), 1.0)
    table = breakdown.markdown()
    assert "| 4-8 px | 50.0 % | 20.00 | 100.0 % | 40.00 | 50.0 % |" in table


def test_methods_must_match_and_defocus_maps_are_checked(tmp_path):
    breakdown = BlurBreakdown()
    image = np.zeros((2, 3, 3))
    breakdown.add(np.zeros((2, 3)), {"input": image}, image)
    with pytest.raises(ValueError, match="methods"):
        breakdown.add(np.zeros((2, 3)), {"input": image, "model": image}, image)
    np.save(tmp_path / "small.npy", np.zeros((2, 2), np.float32))
    with pytest.raises(InputFileError, match=r"small\.npy.*defocus map is \(2, 2\)"):
        read_defocus(tmp_path / "small.npy", (2, 3))
    (tmp_path / "junk.npy").write_text("not an array")
    with pytest.raises(InputFileError, match=r"junk\.npy"):
        read_defocus(tmp_path / "junk.npy", (2, 3))
