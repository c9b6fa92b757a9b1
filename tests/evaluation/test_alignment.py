import cv2
import numpy as np
import pytest

from dualpixel.errors import ParameterError
from dualpixel.evaluation.alignment import AlignmentError, align_to_target
from dualpixel.evaluation.metrics import psnr
from dualpixel.evaluation.run import EvaluationRequest, run_evaluation


def _texture(height=120, width=160, seed=0):
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.standard_normal((height, width, 3)).astype(np.float32), (0, 0), 2)
    return np.clip(0.5 + 2.0 * noise, 0, 1).astype(np.float32)


def _moved(image, matrix):
    """``image`` sampled at ``matrix @ (x, y, 1)``: the content moves by the inverse map."""
    return np.clip(cv2.warpAffine(image, matrix, image.shape[1::-1],
                                  flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                                  borderMode=cv2.BORDER_REFLECT), 0, 1)


@pytest.mark.parametrize("mode, matrix", [
    ("translation", [[1, 0, 0.6], [0, 1, -0.4]]),
    ("affine", [[1.003, 0.001, 0.3], [-0.001, 0.998, 0.5]]),
])
def test_registration_recovers_a_subpixel_move(mode, matrix):
    target = _texture()
    matrix = np.array(matrix, np.float32)
    output = _moved(target, matrix)
    pair = align_to_target(output, target, mode)
    # the output is registered: far closer than before, and the move is read back
    assert psnr(pair.prediction, pair.target) > psnr(output, target) + 12
    assert pair.warp.shape == (2, 3)
    # the map found moves every pixel to within 0.1 px of where the true inverse moves it
    inverse = cv2.invertAffineTransform(matrix)
    corners = np.array([[0, 0, 1], [159, 0, 1], [0, 119, 1], [159, 119, 1]], np.float64)
    assert np.abs(corners @ (pair.warp - inverse).T).max() < 0.1
    assert 1 <= pair.margin <= 3 and pair.prediction.shape == pair.target.shape
    assert pair.target.shape == (120 - 2 * pair.margin, 160 - 2 * pair.margin, 3)


def test_registration_of_an_aligned_blurred_output_moves_nothing():
    # a symmetric blur does not read as a shift: deblurring outputs are blurred to some degree
    target = _texture(seed=1)
    blurred = cv2.GaussianBlur(target, (0, 0), 2.0)
    pair = align_to_target(blurred, target, "affine")
    assert np.allclose(pair.warp, np.eye(2, 3), atol=0.05)
    assert abs(psnr(pair.prediction, pair.target) - psnr(blurred, target)) < 0.2


def test_registration_refuses_bad_input():
    target = _texture()
    with pytest.raises(ParameterError, match="align mode"):
        align_to_target(target, target, "homography")
    with pytest.raises(ParameterError, match="one size"):
        align_to_target(target[:100], target)
    flat = np.full_like(target, 0.5)
    with pytest.raises(AlignmentError):
        align_to_target(flat, flat, "affine")


def test_evaluation_refuses_an_unknown_align_mode_before_any_work(tmp_path):
    request = EvaluationRequest(output=tmp_path / "report", dataset=tmp_path, align="perspective")
    with pytest.raises(ParameterError, match="align mode must be one of"):
        run_evaluation(request)
    assert not (tmp_path / "report" / "summary.json").exists()
