import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.noise import PAPER_NOISE_SIGMAS, add_noise, sample_noise_sigma
from dualpixel.optics.psf_bank import PAPER_PSF_BANK, PSFBank

LEVELS = torch.tensor([0.05, 0.1, 0.2, 0.4, 0.8], dtype=torch.float64)


def noise_std(model, **kwargs):
    image = LEVELS[:, None].expand(-1, 200_000).clone()
    gen = torch.Generator().manual_seed(1)
    noisy = add_noise(image, generator=gen, model=model, **kwargs)
    return (noisy - image).std(dim=1)


def test_default_noise_std_is_proportional_to_intensity():
    std = noise_std("multiplicative", sigma=0.1)
    ratio = std / LEVELS
    torch.testing.assert_close(ratio, torch.full_like(ratio, 0.1), rtol=0.02, atol=0)


def test_poisson_gaussian_variance_is_affine_in_intensity():
    a, b = 0.01, 0.02**2
    variance = noise_std("poisson-gaussian", sigma=a**0.5, read_noise=b**0.5) ** 2
    slope, intercept = np.polyfit(LEVELS.numpy(), variance.numpy(), 1)
    assert slope == pytest.approx(a, rel=0.05)
    assert intercept == pytest.approx(b, rel=0.1)
    # and it is not proportional: the std ratio changes with intensity
    ratio = variance.sqrt() / LEVELS
    assert float(ratio[0]) > 2 * float(ratio[-1])


def test_noise_is_seeded_and_views_are_independent():
    image = torch.full((64, 64), 0.5)
    one = add_noise(image, 0.2, generator=torch.Generator().manual_seed(3))
    again = add_noise(image, 0.2, generator=torch.Generator().manual_seed(3))
    other = add_noise(image, 0.2, generator=torch.Generator().manual_seed(4))
    assert torch.equal(one, again)
    correlation = np.corrcoef((one - image).flatten(), (other - image).flatten())[0, 1]
    assert abs(correlation) < 0.05


def test_paper_sets():
    assert PAPER_NOISE_SIGMAS[0] == 0.05 and PAPER_NOISE_SIGMAS[-1] == 0.5
    assert len(PAPER_NOISE_SIGMAS) == 91
    assert sample_noise_sigma(np.random.default_rng(5)) in PAPER_NOISE_SIGMAS
    assert len(PAPER_PSF_BANK) == 48
    assert {p.n for p in PAPER_PSF_BANK} == {3, 6, 9}
    assert {p.alpha for p in PAPER_PSF_BANK} == {0.4, 0.6, 0.8, 1.0}
    assert {p.beta for p in PAPER_PSF_BANK} == {0.1, 0.2, 0.3, 0.4}
    assert {p.kappa for p in PAPER_PSF_BANK} == {0.14}


def test_bank_sampling_is_reproducible_and_custom_banks_work():
    draws = [PAPER_PSF_BANK.sample(seed=s) for s in range(20)]
    assert draws == [PAPER_PSF_BANK.sample(seed=s) for s in range(20)]
    assert len(set(draws)) > 5
    custom = PSFBank.from_grid(n=[2], alpha=[0.5], beta=[0.3], kappa=[0.2])
    assert len(custom) == 1 and custom.sample(seed=0).alpha == 0.5
    with pytest.raises(ParameterError):
        PSFBank([])
    with pytest.raises(ParameterError, match="sigma"):
        add_noise(torch.ones(2), -0.1)


def test_tiled_normals_give_a_window_the_whole_frames_draws_there():
    """A frame's noise is drawn in tiles, each from its own seed: any window (across tile
    borders, at the frame's edges) equals that window of the whole frame's draws, the draws
    are standard normal, independent between tiles, and another seed draws others."""
    from dualpixel.optics.noise import NOISE_TILE, tiled_normals

    frame = (NOISE_TILE * 2 + 37, NOISE_TILE * 3 - 5)
    whole = tiled_normals(3, frame, 17)
    assert whole.shape == (3, *frame)
    for top, left, rows, cols in [(0, 0, *frame), (5, 9, 40, 60), (NOISE_TILE - 3, 1, 9, 300),
                                  (frame[0] - 7, frame[1] - 11, 7, 11), (NOISE_TILE, 0, 128, 1)]:
        window = tiled_normals(3, frame, 17, (top, left, rows, cols))
        assert torch.equal(window, whole[:, top : top + rows, left : left + cols])
    assert abs(float(whole.mean())) < 0.01 and abs(float(whole.std()) - 1.0) < 0.01
    tile = NOISE_TILE
    first, second = whole[:, :tile, :tile], whole[:, :tile, tile : 2 * tile]
    assert abs(float((first * second).mean())) < 0.02  # tiles are not copies of each other
    assert not torch.equal(tiled_normals(3, frame, 18), whole)
