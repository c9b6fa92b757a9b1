import numpy as np
import pytest
import torch
import torch.nn.functional as F
from scipy import ndimage

from dualpixel.training.losses import DeblurLoss, EdgeLoss, sobel_factors, sobel_kernels


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


def test_log_reduction_weighs_every_image_the_same_in_db():
    torch.manual_seed(0)
    target = torch.rand(2, 3, 3, 24, 24)
    noise = torch.randn_like(target)
    # Sequence 0 off by 0.01, sequence 1 by 0.1: errors 100x apart.
    output = (target + noise * torch.tensor([0.01, 0.1]).view(2, 1, 1, 1, 1)).requires_grad_()
    mean_loss, parts = DeblurLoss()(output, target)
    log_loss, log_parts = DeblurLoss(reduction="log")(output, target)
    # The parts are batch means either way; the per-image edge terms average to the batch's.
    for key in parts:
        torch.testing.assert_close(parts[key], log_parts[key])
    # The total is the mean over the 6 frames of each frame's Eq. 16 in dB (up to the 1e-8 that
    # keeps the log finite: 4e-4 dB here).
    per_frame = [DeblurLoss()(output[b, t], target[b, t])[0] for b in range(2) for t in range(3)]
    expected = torch.stack([10 * torch.log10(v) for v in per_frame]).mean()
    torch.testing.assert_close(log_loss, expected, rtol=0, atol=1e-3)
    # Gradient share of the nearly right sequence: negligible under the mean, equal under log.
    (grad_mean,) = torch.autograd.grad(mean_loss, output)
    (grad_log,) = torch.autograd.grad(log_loss, output)
    mean_ratio = grad_mean[0].norm() / grad_mean[1].norm()
    log_ratio = grad_log[0].norm() / grad_log[1].norm()
    assert mean_ratio < 0.2 and log_ratio > 5  # 0.1 vs 10: the weights turn over
    with pytest.raises(ValueError, match="reduction"):
        DeblurLoss(reduction="sum")


@pytest.mark.parametrize("per_image", [False, True])
def test_edge_loss_matches_the_2d_sobel_convolution(per_image):
    # The separable, difference-based computation gives Eq. 15 as written: each image filtered
    # with the 2-D kernels (valid region), squared differences averaged, scales averaged.
    torch.manual_seed(0)
    output = torch.rand(2, 3, 3, 40, 36, dtype=torch.float64, requires_grad=True)
    target = torch.rand(2, 3, 3, 40, 36, dtype=torch.float64)
    sizes = (3, 7, 11)
    lx, ly = EdgeLoss(sizes)(output, target, per_image=per_image)

    def grads(image, size):
        kx, ky = (torch.from_numpy(k) for k in sobel_kernels(size))
        planes = image.reshape(-1, 1, *image.shape[-2:])
        return [F.conv2d(planes, k[None, None]).unflatten(0, (6, 3))[:, :, 0] for k in (kx, ky)]

    expected = []
    for axis in (0, 1):
        terms = [(grads(output, s)[axis] - grads(target, s)[axis]).square() for s in sizes]
        dims = (1, 2, 3) if per_image else (0, 1, 2, 3)
        expected.append(sum(t.mean(dim=dims) for t in terms) / len(sizes))
    torch.testing.assert_close(lx, expected[0])
    torch.testing.assert_close(ly, expected[1])
    # Gradients too (training follows them).
    (got,) = torch.autograd.grad((lx + 2 * ly).sum(), output)
    (want,) = torch.autograd.grad((expected[0] + 2 * expected[1]).sum(), output)
    torch.testing.assert_close(got, want)


def test_sobel_factors_multiply_to_the_kernels():
    for size in (3, 5, 7, 11, 31):
        smoothing, derivative = sobel_factors(size)
        np.testing.assert_allclose(np.outer(smoothing, derivative), sobel_kernels(size)[0])
        assert smoothing.shape == derivative.shape == (size,)


@pytest.mark.parametrize("reduction", ["mean", "log"])
def test_charbonnier_pixel_term_finds_the_median_where_mse_finds_the_mean(reduction):
    """Edge terms off, one output level fitted to a target whose pixels are a quarter 1 and the
    rest 0: MSE settles at their mean (0.25), the Charbonnier term near their median (0); the
    reported ``mse`` part is the MSE either way."""
    target = torch.zeros(2, 3, 16, 16)
    target[..., :4, :] = 1.0  # a quarter of the pixels
    found = {}
    for pixel in ("mse", "charbonnier"):
        loss = DeblurLoss(lambda_x=0.0, lambda_y=0.0, reduction=reduction, pixel=pixel)
        level = torch.full((1,), 0.5, requires_grad=True)
        optimiser = torch.optim.Adam([level], lr=0.01)
        for _ in range(400):
            optimiser.zero_grad()
            total, parts = loss(level.expand_as(target), target)
            total.backward()
            optimiser.step()
        found[pixel] = float(level)
        assert float(parts["mse"]) == pytest.approx(
            float(((level.detach() - target) ** 2).mean()), rel=1e-5)
    assert found["mse"] == pytest.approx(0.25, abs=0.02)
    assert found["charbonnier"] < 0.05
    with pytest.raises(ValueError, match="pixel"):
        DeblurLoss(pixel="l3")
