import numpy as np
import pytest
import torch
import torch.nn.functional as F
from scipy import ndimage

from dualpixel.training.losses import DeblurLoss, EdgeLoss, sobel_kernels


def test_sobel_kernels_are_the_extended_sobel_normalised():
    kx, ky = sobel_kernels(3)
    np.testing.assert_allclose(kx, np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]]) / 2)
    np.testing.assert_allclose(ky, kx.T)
    k7, _ = sobel_kernels(7)
    np.testing.assert_allclose(k7[3], np.array([-20, -80, -100, 0, 100, 80, 20]) / 100)
    k11, _ = sobel_kernels(11)
    assert np.abs(k11).max() == 1.0 and np.abs(k11 * 12096).max() == pytest.approx(12096)
    with pytest.raises(ValueError):
        sobel_kernels(4)


def test_edge_loss_zero_for_identical_positive_for_blurred():
    rng = np.random.default_rng(0)
    sharp = torch.from_numpy(rng.random((2, 3, 3, 32, 32), dtype=np.float32))
    blurred = torch.from_numpy(
        ndimage.gaussian_filter(sharp.numpy(), sigma=(0, 0, 0, 2, 2))
    )
    loss = EdgeLoss()
    zero_x, zero_y = loss(sharp, sharp)
    assert float(zero_x) == 0 and float(zero_y) == 0
    lx, ly = loss(blurred, sharp)
    assert float(lx) > 1e-3 and float(ly) > 1e-3


def test_directions_are_separate_and_every_batch_element_counts():
    x = torch.arange(32, dtype=torch.float32).repeat(32, 1) / 32  # varies along the width only
    ramp = x.expand(2, 1, 3, 32, 32).clone()
    flat = torch.zeros_like(ramp)
    lx, ly = EdgeLoss()(ramp, flat)
    assert float(lx) > 0.1 and float(ly) < 1e-10
    # A difference only in batch element 1 still counts (the reference used element 0 only).
    target = ramp.clone()
    target[1] = 0
    lx, _ = EdgeLoss()(ramp, target)
    assert float(lx) > 0


def test_total_loss_is_eq16():
    torch.manual_seed(0)
    out, tgt = torch.rand(1, 2, 3, 24, 24), torch.rand(1, 2, 3, 24, 24)
    total, parts = DeblurLoss(lambda_x=0.03, lambda_y=0.02)(out, tgt)
    expected = F.mse_loss(out, tgt) + 0.03 * parts["edge_x"] + 0.02 * parts["edge_y"]
    torch.testing.assert_close(total, expected)
    # The single 3x3 Sobel loss of the ablation is a special case.
    _, single = DeblurLoss(sizes=(3,))(out, tgt)
    assert float(single["edge_x"]) != float(parts["edge_x"])
