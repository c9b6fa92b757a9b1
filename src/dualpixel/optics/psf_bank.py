"""The bank of PSF shapes used for synthesis (paper Sec. 5, supplement S2)."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from dualpixel.errors import ParameterError
from dualpixel.names import PSF_BANK_NAMES
from dualpixel.optics.psf import PSFParams

__all__ = ["BROAD_PSF_BANK", "PAPER_PSF_BANK", "PIXEL4_PSF_BANK", "PSF_BANKS", "PSFBank"]


class PSFBank(Sequence[PSFParams]):
    """An ordered set of :class:`PSFParams` to draw from reproducibly.

    >>> len(PAPER_PSF_BANK)
    48
    >>> PAPER_PSF_BANK.sample(seed=0) == PAPER_PSF_BANK.sample(seed=0)
    True
    """

    def __init__(self, params: Iterable[PSFParams]) -> None:
        self._params = tuple(params)
        if not self._params:
            raise ParameterError("a PSF bank needs at least one parameter set")

    @classmethod
    def from_grid(
        cls,
        n: Sequence[float],
        alpha: Sequence[float],
        beta: Sequence[float],
        kappa: Sequence[float],
    ) -> PSFBank:
        """Every combination of the given values (the paper's bank is a 3 x 4 x 4 x 1 grid)."""
        return cls(PSFParams(*values) for values in itertools.product(n, alpha, beta, kappa))

    def __len__(self) -> int:
        return len(self._params)

    def __getitem__(self, index):  # type: ignore[override]
        return self._params[index]

    def __iter__(self) -> Iterator[PSFParams]:
        return iter(self._params)

    def sample(
        self, rng: np.random.Generator | None = None, *, seed: int | None = None
    ) -> PSFParams:
        """Draw one parameter set uniformly from ``rng``, or from a generator seeded by ``seed``."""
        generator = rng if rng is not None else np.random.default_rng(seed)
        return self._params[int(generator.integers(len(self._params)))]


#: n in {3, 6, 9}, alpha in {0.4, 0.6, 0.8, 1.0}, beta in {0.1, 0.2, 0.3, 0.4}, kappa = 0.14.
PAPER_PSF_BANK = PSFBank.from_grid(
    n=(3, 6, 9), alpha=(0.4, 0.6, 0.8, 1.0), beta=(0.1, 0.2, 0.3, 0.4), kappa=(0.14,)
)

#: Drawn around our S2 fits to the 48 real Pixel 4 PSF pairs (README "Calibration"): alpha mostly
#: 0.4-0.5, beta 0.1-0.3, kappa mostly 0.21, n poorly determined (2, 3, 7 and 15 all common).
PIXEL4_PSF_BANK = PSFBank.from_grid(
    n=(2, 3, 7, 15), alpha=(0.35, 0.45, 0.55), beta=(0.1, 0.2, 0.3), kappa=(0.17, 0.21, 0.25)
)

#: Ours: the Pixel 4 bank's orders and cutoffs with a wider range of centre depletion (beta up
#: to 0.9, nearly a full disk) and smoothing (kappa 0.05 sharp-edged to 0.45 soft), so that a
#: network meets view PSFs fuller or smoother than one camera's fit (192 shapes).
BROAD_PSF_BANK = PSFBank.from_grid(
    n=(2, 3, 7, 15), alpha=(0.35, 0.45, 0.55), beta=(0.1, 0.3, 0.6, 0.9),
    kappa=(0.05, 0.14, 0.25, 0.45)
)

#: Banks by name (``dualpixel synth --psf-bank``).
PSF_BANKS: dict[str, PSFBank] = dict(
    zip(PSF_BANK_NAMES, (PAPER_PSF_BANK, PIXEL4_PSF_BANK, BROAD_PSF_BANK), strict=True)
)
