"""Checks that a DP pair is what the models expect, naming the likely mistake when it is not.

The models take each view at the brightness of the combined image (the DPDD convention: the
combined image is the views' mean) and the left view as the camera's left. Two mistakes pass
every size check and still ruin the output: views exchanged (about -1.3 dB on Canon scenes, worse
than the input on some) and views at half brightness, as a raw A/B split gives them (12 dB
outputs). :func:`check_views` measures both, and the rest it can tell, from the images alone.

How "swapped" is told: in a photograph most defocused content lies behind the focus plane, and
behind the focus plane the right view shows it shifted to the right of the left view's (on all
7 Canon dev scenes, 83-100 % of the defocused 64-px blocks at 1620x980 shift that way). When most
defocused blocks shift the other way, the views are likely exchanged; a photograph whose blur is
mostly in front of the focus plane can trip it, which is why it is a warning unless ``strict``.

How "block-coded" is told: a JPEG or video coder works on blocks of 8 px (or multiples), and
what it drops leaves steps on that grid; the models, trained on views stored losslessly, sharpen
those steps into texture. :func:`blockiness` compares the mean step across each of the eight
column (and row) phases with their median: uncoded photographs and synthetic views stay under
1.06 (the real pairs of ``dp-real-nogt`` stored as stills or GIF frames, the held-out sets of
procedural scenes), JPEG frames at quality 80 and most video frames lie above 1.1. Views
synthesised from JPEG photographs keep some of their grid: on the photographic held-out sets
(scenes of ``../shared/data/photographs``, quality 95) 0-3 frames of 44 reach 1.10-1.13.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dualpixel.data.statistics import defocus_shift_counts
from dualpixel.filters import channel_mean

__all__ = ["ViewFinding", "blockiness", "check_views", "views_from_sum"]

#: Share of defocused blocks shifting the front-of-focus way that reads as "swapped".
SWAPPED_SHARE = 0.7
#: Lowest PSNR (dB) between the views' mean and the combined image for one capture.
SAME_CAPTURE_PSNR = 30.0
#: :func:`blockiness` from which a view reads as block-coded.
BLOCK_CODED = 1.10
#: Side (px) of the coders' blocks whose steps :func:`blockiness` looks for.
CODER_BLOCK = 8
#: Fewest blocks each way :func:`blockiness` judges: on smaller images the eight phases' means
#: differ by chance as much as a coder's grid makes them.
FEWEST_BLOCKS = 32
#: Pixels whose value percentiles the checks read at most (larger views: every n-th row and
#: column); a warning's threshold needs no more.
PERCENTILE_PIXELS = 2**19


@dataclass(frozen=True)
class ViewFinding:
    """One problem with a DP pair: a short ``code`` and a message that says what to do."""

    code: str  # swapped | half-bright | brightness | unbalanced | not-combined | bit-depth
    #            | block-coded
    message: str


def thinned(image: np.ndarray, pixels: int = PERCENTILE_PIXELS) -> np.ndarray:
    """``image`` ``(H, W, ...)`` at every n-th row and column, the smallest n that leaves at
    most about ``pixels`` (a view for the checks' percentiles; no copy)."""
    stride = max(1, math.ceil(math.sqrt(image.shape[0] * image.shape[1] / pixels)))
    return image[::stride, ::stride]


def views_from_sum(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Views that sum to the combined image (a raw A/B split) at the combined image's
    brightness, as the models take them: each doubled, clipped to [0, 1]."""
    return np.clip(2.0 * left, 0.0, 1.0), np.clip(2.0 * right, 0.0, 1.0)


def blockiness(view: np.ndarray) -> float | None:
    """How much a coder's block grid shows in ``view`` (``(H, W, C)`` or ``(H, W)`` in [0, 1]):
    per direction, the mean absolute step between neighbouring pixels at each of the
    :data:`CODER_BLOCK` phases of the grid, the largest over their median; the smaller of the
    two directions (a coder's grid runs both ways; one without any step counts 1). About 1 for
    an uncoded image; None for one under :data:`FEWEST_BLOCKS` blocks either way.

    >>> rng = np.random.default_rng(0)
    >>> blockiness(rng.random((256, 256))) < BLOCK_CODED
    True
    >>> blockiness(np.kron(rng.random((32, 32)), np.ones((8, 8)))) > 10  # constant 8-px blocks
    True
    """
    grey = channel_mean(view) if np.ndim(view) == 3 else np.asarray(view, np.float32)
    if min(grey.shape) < FEWEST_BLOCKS * CODER_BLOCK:
        return None
    ratios = []
    for axis in (1, 0):
        steps = np.abs(np.diff(grey, axis=axis)).mean(axis=1 - axis)
        usable = steps.size // CODER_BLOCK * CODER_BLOCK
        phases = steps[:usable].reshape(-1, CODER_BLOCK).mean(axis=0)
        if phases.max() <= 1e-12:  # no step at all this way: no grid to see
            ratios.append(1.0)
            continue
        ratios.append(float(phases.max() / max(float(np.median(phases)), 1e-12)))
    return min(ratios)


def _block_coded(left: np.ndarray) -> ViewFinding | None:
    found = blockiness(left)
    if found is None or found < BLOCK_CODED:
        return None
    return ViewFinding("block-coded", (
        f"the views look block-coded (a JPEG or video frame: steps on an {CODER_BLOCK}-px grid "
        f"{found:.2f}x those between it): the models sharpen a coder's blocks into texture; "
        "give views stored losslessly (PNG, TIFF, developed from raw) if you have them"))


def _swapped(left: np.ndarray, right: np.ndarray) -> ViewFinding | None:
    counts = defocus_shift_counts(left, right)
    if counts is None:
        return None
    backward, total = counts[1], sum(counts)
    if backward < SWAPPED_SHARE * total:
        return None
    return ViewFinding("swapped", (
        f"views look swapped: {backward} of {total} defocused regions shift the way "
        "content in front of the focus plane does, which in most photographs means left and "
        "right are exchanged; pass the other view as the left"))


def _brightness(left: np.ndarray, right: np.ndarray,
                combined: np.ndarray | None) -> list[ViewFinding]:
    mean_left, mean_right = float(left.mean()), float(right.mean())
    findings = []
    if min(mean_left, mean_right) > 0.01:
        ratio = mean_left / mean_right
        if not 0.8 <= ratio <= 1.25:
            findings.append(ViewFinding("unbalanced", (
                f"the left view is {ratio:.2f}x as bright as the right; DP views of one capture "
                "are about equally bright: are both from the same photograph?")))
    if combined is None:
        brightest = max(np.percentile(thinned(view), 99.9) for view in (left, right))
        if brightest <= 0.51 and max(mean_left, mean_right) > 0.02:
            findings.append(ViewFinding("half-bright", (
                "the views never exceed half of full scale, as views that sum to the combined "
                "image do (a raw A/B split): if they are such halves, pass --views-sum "
                "(views_sum=True) or scale them by 2; if the photograph is just dark (as raw "
                "phone views often are), nothing needs doing")))
        return findings
    mean_combined = float(combined.mean())
    if mean_combined <= 0.01:
        return findings
    scale = (mean_left + mean_right) / (2.0 * mean_combined)
    if abs(scale - 0.5) < 0.08:
        findings.append(ViewFinding("half-bright", (
            f"the views are {scale:.2f}x as bright as the combined image: they sum to it (a raw "
            "A/B split) but the models take each view as bright as the combined image; pass "
            "--views-sum (views_sum=True), or scale them by 2")))
    elif abs(scale - 1.0) > 0.1:
        findings.append(ViewFinding("brightness", (
            f"the views are {scale:.2f}x as bright as the combined image; the models take each "
            "view as bright as the combined image (its mean is the combined image)")))
    else:
        error = float(np.mean(((left + right) / (2.0 * scale) - combined) ** 2))
        psnr = 10.0 * np.log10(1.0 / max(error, 1e-12))
        if psnr < SAME_CAPTURE_PSNR:
            findings.append(ViewFinding("not-combined", (
                f"the combined image is not the views' mean ({psnr:.1f} dB apart; one capture "
                f"gives {SAME_CAPTURE_PSNR:.0f} dB or more): is it from another photograph?")))
    return findings


def check_views(
    left: np.ndarray, right: np.ndarray, *, combined: np.ndarray | None = None,
    bit_depths: tuple[int, int] | None = None, orientation_known: bool = False,
) -> list[ViewFinding]:
    """Likely mistakes in a DP pair, most serious first (empty when none is seen).

    Args:
        left, right: ``(H, W, 3)`` views in [0, 1], of one size.
        combined: the combined image of the same capture, if there is one (brightness and
            same-capture checks).
        bit_depths: the files' bit depths ``(left, right)``, if read from files.
        orientation_known: the left view is known to be the camera's left (a synthesised
            pair), so the guess that the views are exchanged is not made.
    """
    findings = []
    if bit_depths is not None and bit_depths[0] != bit_depths[1]:
        findings.append(ViewFinding("bit-depth", (
            f"the left view is {bit_depths[0]}-bit and the right {bit_depths[1]}-bit: are they "
            "from the same export?")))
    findings += _brightness(left, right, combined)
    coded = _block_coded(left)
    swapped = None if orientation_known else _swapped(left, right)
    return ([swapped] if swapped else []) + findings + ([coded] if coded else [])
