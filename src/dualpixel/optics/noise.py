"""Signal-dependent sensor noise (paper Sec. 2.3).

The paper's formula, the default: ``I_noise = I + I o N`` with ``N ~ N(0, sigma^2)``, whose standard
deviation is proportional to intensity. (The paper's text says the *variance* is proportional to
intensity, as in the model of Foi et al. 2008 it cites; that model is available as
``model="poisson-gaussian"``: ``I_noise = I + sqrt(a I + b) N(0, 1)``.)
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import torch

from dualpixel.errors import ParameterError, check_range

__all__ = [
    "NOISE_TILE", "PAPER_NOISE_SIGMAS", "NoiseModel", "add_noise", "check_noise_sigmas",
    "sample_noise_sigma", "tiled_normals",
]

NoiseModel = Literal["multiplicative", "poisson-gaussian"]

#: The paper's noise strengths {0.05, 0.055, ..., 0.5} (Sec. 5).
PAPER_NOISE_SIGMAS: tuple[float, ...] = tuple(
    round(0.05 + 0.005 * i, 4) for i in range(91)
)


#: Side (px) of the tiles a frame's noise is drawn in, each from its own seed: a window of the
#: frame (a training crop) draws only the tiles it touches and gets the frame's noise there.
NOISE_TILE = 128


def tiled_normals(channels: int, frame: tuple[int, int], seed: int,
                  window: tuple[int, int, int, int] | None = None, *,
                  dtype: torch.dtype = torch.float32, device: torch.device | str = "cpu"
                  ) -> torch.Tensor:
    """Standard normal draws for a ``(channels, H, W)`` frame (``frame`` ``(H, W)``), fixed by
    ``seed``: ``(channels, h, w)`` of ``window`` ``(top, left, h, w)`` px, or of the whole frame.
    The frame is drawn in :data:`NOISE_TILE` tiles, each with its own generator (seeded from
    ``seed`` and its place), so a window draws only the tiles it touches and equals that
    window of the whole frame's draws."""
    height, width = frame
    top, left, rows, cols = window if window is not None else (0, 0, height, width)
    out = torch.empty((channels, rows, cols), dtype=dtype, device=device)
    tile = NOISE_TILE
    for row in range(top // tile * tile, top + rows, tile):
        for col in range(left // tile * tile, left + cols, tile):
            state = np.random.SeedSequence((seed, row // tile, col // tile)).generate_state(
                1, dtype=np.uint64)[0]
            generator = torch.Generator(device=device).manual_seed(int(state))
            draws = torch.randn((channels, min(tile, height - row), min(tile, width - col)),
                                generator=generator, dtype=dtype, device=device)
            r0, c0 = max(row, top), max(col, left)
            r1, c1 = min(row + tile, top + rows), min(col + tile, left + cols)
            out[:, r0 - top : r1 - top, c0 - left : c1 - left] = \
                draws[:, r0 - row : r1 - row, c0 - col : c1 - col]
    return out


def check_noise_sigmas(sigmas) -> tuple[float, ...]:
    """The noise strengths as a tuple, refused unless at least one, each finite in [0, 1]."""
    values = tuple(sigmas)
    if not values:
        raise ParameterError("noise_sigmas must hold at least one value")
    return tuple(check_range("noise_sigmas", sigma, 0.0, 1.0) for sigma in values)


def sample_noise_sigma(rng: np.random.Generator, sigmas=PAPER_NOISE_SIGMAS) -> float:
    """Draw one noise strength uniformly from ``sigmas`` (the paper's set by default)."""
    return float(sigmas[int(rng.integers(len(sigmas)))])


def add_noise(
    image: torch.Tensor,
    sigma: float,
    *,
    generator: torch.Generator | None = None,
    model: NoiseModel = "multiplicative",
    read_noise: float = 0.0,
    gaussian: torch.Tensor | None = None,
) -> torch.Tensor:
    """Add signal-dependent Gaussian noise to an image with values in [0, 1] (not clipped).

    Args:
        image: float tensor, any shape.
        sigma: "multiplicative": std of N, so std(I_noise) = sigma * I. "poisson-gaussian": the
            signal-dependent coefficient a = sigma**2 of variance = a I + b.
        generator: torch generator for reproducible draws (use one per view: independent noise).
        model: "multiplicative" (the paper's formula) or "poisson-gaussian" (Foi et al. 2008).
        read_noise: for "poisson-gaussian", the signal-independent std, b = read_noise**2.
        gaussian: the standard normal draws to use, ``image``'s shape (e.g. a crop's region of
            its whole frame's draws); None draws them from ``generator``.

    Returns:
        The noisy image, same shape, dtype and device; clip it yourself if needed.
    """
    check_range("sigma", sigma, 0.0)
    check_range("read_noise", read_noise, 0.0)
    if gaussian is None:
        gaussian = torch.randn(
            image.shape, generator=generator, dtype=image.dtype, device=image.device
        )
    elif gaussian.shape != image.shape:
        raise ParameterError(f"gaussian draws {tuple(gaussian.shape)} and image "
                             f"{tuple(image.shape)} differ in shape")
    if model == "multiplicative":
        return image + image * (sigma * gaussian)
    if model == "poisson-gaussian":
        variance = (sigma**2) * image.clamp_min(0.0) + read_noise**2
        return image + torch.sqrt(variance) * gaussian
    raise ParameterError(
        f"noise model must be 'multiplicative' or 'poisson-gaussian', got {model!r}"
    )
