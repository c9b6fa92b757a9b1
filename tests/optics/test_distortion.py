import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.distortion import (
    DISTORTION_PRESETS,
    DivisionDistortion,
    distort_image,
    distort_points,
    undistort_points,
)


@pytest.mark.parametrize("name", list(DISTORTION_PRESETS))
@pytest.mark.parametrize(("width", "height"), [(1920, 1080), (97, 131)])
def test_inverse_round_trips_points(name, width, height):
    gen = torch.Generator().manual_seed(0)
    points = torch.rand(5000, 2, generator=gen, dtype=torch.float64)
    points = points * torch.tensor([width - 1.0, height - 1.0], dtype=torch.float64)
    d = DISTORTION_PRESETS[name]
    there = distort_points(points, d, width, height)
    back = undistort_points(there, d, width, height)
    assert float((back - points).abs().max()) < 0.01
    forth = distort_points(undistort_points(points, d, width, height), d, width, height)
    assert float((forth - points).abs().max()) < 0.01


def test_equation_five_by_hand_and_barrel_vs_pincushion():
    width, height = 200, 100
    half_diag = 0.5 * np.hypot(width, height)
    d = DivisionDistortion(0.1, 0.05, 0.0)
    point = torch.tensor([[199.5, 99.5]], dtype=torch.float64)
    centre = torch.tensor([99.5, 49.5], dtype=torch.float64)
    radius = float((point - centre).norm()) / half_diag
    expected = centre + (point - centre) / (1 + 0.1 * radius**2 + 0.05 * radius**4)
    torch.testing.assert_close(distort_points(point, d, width, height), expected)
    barrel = distort_points(point, DISTORTION_PRESETS["set0"], width, height)
    pincushion = distort_points(point, DISTORTION_PRESETS["set4"], width, height)
    assert float((barrel - centre).norm()) < float((point - centre).norm())
    assert float((pincushion - centre).norm()) > float((point - centre).norm())


def test_image_warp_moves_content_where_the_points_go():
    width, height = 121, 81
    image = torch.zeros(1, height, width, dtype=torch.float64)
    image[0, 70, 110] = 1.0  # a dot near the corner
    d = DivisionDistortion(0.2, 0.0, 0.0)
    warped = distort_image(image, d, padding_mode="zeros")
    expected = distort_points(torch.tensor([[110.0, 70.0]], dtype=torch.float64), d, width, height)
    ys, xs = torch.meshgrid(torch.arange(height), torch.arange(width), indexing="ij")
    mass = warped[0].sum()
    found = torch.stack(((warped[0] * xs).sum() / mass, (warped[0] * ys).sum() / mass))
    assert float((found - expected[0]).abs().max()) < 0.5


def test_identity_and_shapes():
    image = torch.rand(2, 3, 17, 23)
    out = distort_image(image, DivisionDistortion())
    torch.testing.assert_close(out, image, atol=1e-5, rtol=0)
    assert distort_image(image[0], DISTORTION_PRESETS["set1"]).shape == (3, 17, 23)


def test_folding_coefficients_are_rejected():
    with pytest.raises(ParameterError, match="fold"):
        distort_image(torch.rand(1, 8, 8), DivisionDistortion(-0.5, -0.5, -0.5))


def test_cached_grid_gives_the_same_warp_and_keeps_gradients():
    """The grid is made once per size and distortion; one first made under inference mode (as
    inference makes it) still serves a warp that records gradients."""
    from dualpixel.optics.distortion import _sampling_grid

    d = DivisionDistortion(0.07, -0.01, 0.02, name="test-cache")
    _sampling_grid.cache_clear()
    image = torch.rand(3, 29, 37, generator=torch.Generator().manual_seed(1))
    with torch.inference_mode():
        first = distort_image(image, d)
    again = distort_image(image, d)
    assert _sampling_grid.cache_info().hits == 1
    assert torch.equal(first, again)
    source = image.clone().requires_grad_(True)
    distort_image(source, d).sum().backward()
    assert source.grad is not None and float(source.grad.abs().sum()) > 0


def test_grid_cache_holds_every_preset_in_every_variant_a_gpu_run_asks_for():
    """On-the-fly training that renders on a GPU asks for each preset's grid in float32 and
    float64 on the CPU and on the GPU, at each frame size: a second round of those (here two
    dtypes on the CPU stand in for four variants, at four sizes) is read from the cache."""
    from dualpixel.optics.distortion import _sampling_grid

    _sampling_grid.cache_clear()
    variants = [(preset, size, dtype) for preset in DISTORTION_PRESETS.values()
                for size in ((12, 9), (14, 10), (16, 11), (18, 13))
                for dtype in (torch.float32, torch.float64)]
    for _ in range(2):
        for preset, (width, height), dtype in variants:
            _sampling_grid(preset, width, height, dtype, torch.device("cpu"))
    assert _sampling_grid.cache_info().misses == len(variants)
