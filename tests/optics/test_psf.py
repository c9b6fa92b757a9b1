import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.psf import PSF_MODELS, PSFParams, dp_psf

RADII = [-15.0, -7.3, -2.0, -0.4, 0.0, 0.3, 1.0, 4.5, 12.0, 25.0]


def centroid_x(kernel: torch.Tensor) -> float:
    x = torch.arange(kernel.shape[-1], dtype=kernel.dtype) - kernel.shape[-1] // 2
    return float((kernel.sum(dim=-2) * x).sum() / kernel.sum())


@pytest.mark.parametrize("model", PSF_MODELS)
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_views_sum_to_half_and_combined_to_one(model, dtype):
    k = dp_psf(RADII, model=model, dtype=dtype)
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    assert k.left.dtype == dtype
    torch.testing.assert_close(k.left.sum((-2, -1)), torch.full((len(RADII),), 0.5, dtype=dtype),
                               atol=tol, rtol=0)
    torch.testing.assert_close(k.combined.sum((-2, -1)), torch.ones(len(RADII), dtype=dtype),
                               atol=2 * tol, rtol=0)
    assert bool((k.left >= 0).all()) and bool((k.right >= 0).all())


@pytest.mark.parametrize("model", PSF_MODELS)
def test_right_is_exact_mirror_of_left(model):
    k = dp_psf(RADII, model=model)
    assert torch.equal(k.right, torch.flip(k.left, dims=(-1,)))


@pytest.mark.parametrize("model", PSF_MODELS)
def test_sign_of_radius_swaps_the_views(model):
    radii = torch.tensor([1.5, 6.0, 17.0], dtype=torch.float64)
    front, back = dp_psf(-radii, model=model), dp_psf(radii, model=model)
    torch.testing.assert_close(front.left, back.right, atol=1e-12, rtol=0)
    torch.testing.assert_close(front.right, back.left, atol=1e-12, rtol=0)


@pytest.mark.parametrize("model", PSF_MODELS)
def test_centroids_separate_monotonically_and_coincide_at_focus(model):
    radii = np.arange(0.0, 20.01, 0.25)
    k = dp_psf(radii, model=model, size=71, dtype=torch.float64)
    separation = np.array([centroid_x(rk) - centroid_x(lk) for lk, rk in zip(k.left, k.right)])
    assert abs(separation[0]) < 1e-12  # r = 0: both views are the same delta
    assert np.all(np.diff(separation) >= -1e-9)
    assert np.all(np.diff(separation[radii >= 1.0]) > 0)
    # behind focus the left view's mass sits on the left (the left image moves left)
    assert centroid_x(k.left[-1]) < 0 < centroid_x(k.right[-1])


def test_zero_radius_is_a_delta():
    k = dp_psf(0.0, dtype=torch.float64)
    centre = k.left.shape[-1] // 2
    assert float(k.left[centre, centre]) == pytest.approx(0.5)
    assert float(k.combined.sum()) == pytest.approx(1.0)
    assert float(k.combined.max()) == pytest.approx(1.0)


@pytest.mark.parametrize("model", PSF_MODELS)
def test_kernels_change_continuously_with_radius(model):
    radii = np.arange(0.0, 6.0, 0.01)
    k = dp_psf(radii, model=model, size=31, dtype=torch.float64)
    jumps = (k.left[1:] - k.left[:-1]).abs().amax(dim=(-2, -1))
    # a 0.01 px change of r never moves any weight by more than a few percent of the peak
    assert float(jumps.max()) < 0.03


@pytest.mark.parametrize("order", [3, 6, 9])
def test_low_alpha_gives_the_donut_of_real_dp_psfs(order):
    radius = 12.0
    combined = dp_psf(radius, PSFParams(n=order, alpha=0.4, beta=0.2), dtype=torch.float64).combined
    c = combined.shape[-1] // 2
    rim = combined[c, c + int(0.85 * radius)]
    assert float(combined[c, c]) < float(rim)
    # alpha = 1 pushes the 3 dB point out to the diameter: almost flat, no donut
    flat = dp_psf(radius, PSFParams(n=order, alpha=1.0, beta=0.2), dtype=torch.float64).combined
    assert float(flat[c, c]) >= 0.95 * float(flat[c, c + int(0.5 * radius)])


def test_numpy_output_and_torch_batch_agree():
    batch = dp_psf(torch.tensor([3.0, -5.0], dtype=torch.float64))
    single = dp_psf(-5.0, size=batch.left.shape[-1], dtype=torch.float64)
    left, right, combined = single.numpy()
    assert isinstance(left, np.ndarray) and left.dtype == np.float64
    np.testing.assert_allclose(left, batch.left[1].numpy(), atol=1e-12)
    np.testing.assert_allclose(combined, left + right)


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [("n", 0.5, "[1, 30]"), ("alpha", 0.0, "(0, 2]"), ("beta", 1.5, "(0, 1]"),
     ("kappa", -0.1, "[0, 1)"), ("kappa", 1.0, "[0, 1)")],
)
def test_out_of_range_parameters_name_the_parameter_and_range(field, value, allowed):
    with pytest.raises(ParameterError, match=rf"{field} must be in \{allowed[0]}"):
        PSFParams(**{field: value})


def test_bad_radius_and_size_are_rejected():
    with pytest.raises(ParameterError, match="radius must be finite"):
        dp_psf(float("nan"))
    with pytest.raises(ParameterError, match="size must be a positive odd integer"):
        dp_psf(3.0, size=10)
    with pytest.raises(ParameterError, match="model must be one of"):
        dp_psf(3.0, model="airy")


def test_psfs_each_with_its_own_shape_equal_each_made_alone():
    """One batch of radii each with its own shape parameters (the layers of many frames in one
    call) gives exactly the kernels each radius gets alone, smoothed or not (kappa 0)."""
    from dualpixel.optics.psf import dp_psf_each

    shapes = [PSFParams(), PSFParams(n=5.3, alpha=0.77, beta=0.31, kappa=0.0),
              PSFParams(n=2.1, alpha=1.3, beta=0.9, kappa=0.27),
              PSFParams(n=11.0, alpha=0.33, beta=0.07, kappa=0.11)]
    radii = torch.tensor([3.3, -5.7, 0.2, 9.1] * 9, dtype=torch.float32)  # over one chunk of 32
    params = [shapes[k % 4] if k < 18 else shapes[(k + 1) % 4] for k in range(len(radii))]
    each = dp_psf_each(radii, params, 25)
    for k, (radius, shape) in enumerate(zip(radii.tolist(), params)):
        alone = dp_psf(torch.tensor([radius]), shape, size=25)
        assert torch.equal(alone.left[0], each.left[k]) and torch.equal(alone.right[0],
                                                                       each.right[k])
    with pytest.raises(ParameterError, match="one PSFParams per radius"):
        dp_psf_each(radii, params[:3], 25)
