"""Analytic gradients of the differentiable operators match finite differences (as
kornia checks its operators): the DP PSF in r, the distortion warp in the image, the edge loss."""

import torch
from torch.autograd import gradcheck

from dualpixel.optics.distortion import DISTORTION_PRESETS, distort_image
from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.training.losses import DeblurLoss


def test_dp_psf_gradient_in_the_radius():
    params = PSFParams(n=3.0, alpha=0.4, beta=0.2, kappa=0.14)

    def kernels(radius):
        k = dp_psf(radius, params, size=15)
        return torch.stack([k.left, k.right])

    radius = torch.tensor([2.3, -3.7], dtype=torch.float64, requires_grad=True)
    assert gradcheck(kernels, (radius,), eps=1e-6, atol=1e-4)


def test_distortion_gradient_in_the_image():
    image = torch.rand(1, 2, 9, 11, dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda x: distort_image(x, DISTORTION_PRESETS["set2"]), (image,),
                     eps=1e-6, atol=1e-5)


def test_edge_loss_gradient():
    criterion = DeblurLoss().double()
    output = torch.rand(2, 3, 16, 16, dtype=torch.float64, requires_grad=True)
    target = torch.rand(2, 3, 16, 16, dtype=torch.float64)
    assert gradcheck(lambda x: criterion(x, target)[0], (output,), eps=1e-6, atol=1e-5)
