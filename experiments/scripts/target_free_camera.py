"""A camera's DP blur from its two views alone (issue #74 item 1, a first measurement).

For views ``L = S * K_l`` and ``R = S * K_r`` of an unknown sharp ``S``, with the camera's
kernels mixed by its disparity ratio ``a`` (``K_l = (1+a)/2 H_l + (1-a)/2 H_r``, as
:mod:`dualpixel.optics.crosstalk` forms views), the cross-convolution identity
``L * K_r = R * K_l`` is linear in ``a`` and reduces to

    P + a Q = 0,   P = (L - R) * H_c,   Q = -C * (H_l - H_r),   H_c = (H_l + H_r) / 2,

the views' difference against the combined image ``C`` through the kernels' odd part. Per block,
channel and radius ``r`` the least-squares ratio is ``a = -<P, Q> / <Q, Q>`` and the share of the
difference it leaves is ``1 - rho^2(P, Q)``; each block takes the radius of least share. Noise
adds ``n sigma^2 ||H_c||^2`` to ``<P, P>`` and a quarter of ``n sigma^2 ||H_l - H_r||^2`` to
``<Q, Q>`` (``sigma^2`` the variance of ``L - R``'s noise, per block by Immerkaer + MAD); both are
taken off, and radii where either signal is below twice its noise count as uninformative.

Measured on a validation photograph rendered by ``canon-840-linear`` (depth ramp 1-7 m, linear
light, 48-px blocks): exact on noiseless kernels (radius and signed ratio recovered to the grid),
ratios 0.67 / 0.93 / 0.97 against the camera's 0.70 / 0.92 / 0.94 and block radii within 0.17 px
(median) without noise, but 0.41 / 0.68 / 0.73 and +0.8 px with the camera's noise (0.03 in
linear light): noise-limited, see ``docs/log/2026-12-02-target-free-camera.md``.

    python experiments/scripts/target_free_camera.py PHOTO [noise|clean]
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import cv2
import numpy as np

import dualpixel
from dualpixel.data.statistics import block_sums
from dualpixel.io.images import read_rgb
from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.optics.tone import srgb_to_linear_array

ROOT = Path(__file__).resolve().parents[2]
PHOTOS = ROOT.parent / "shared" / "data" / "photographs" / "validation"
PATCH = int(os.environ.get("PATCH", 48))
#: Gaussian (px) both views are low-passed by before the fit: the identity holds for any filter
#: applied to both, and the views' noise falls faster than their defocus signal.
SMOOTH = float(os.environ.get("SMOOTH", 0))
RADII = np.arange(0.25, 12.01, 0.25)
IMMERKAER = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


def view_kernels(radius: float, params: PSFParams) -> list[np.ndarray]:
    """Left and right kernels (each summing to 1), flipped for ``cv2.filter2D``."""
    kernels = dp_psf(float(radius), params)
    return [np.ascontiguousarray((2.0 * k.numpy())[::-1, ::-1], np.float32)
            for k in (kernels.left, kernels.right)]


def block_noise_variance(difference: np.ndarray, inner: tuple[slice, slice]) -> np.ndarray:
    """Per block and channel, the variance of the noise of ``difference`` (Immerkaer + MAD)."""
    filtered = np.abs(cv2.filter2D(difference, -1, IMMERKAER, borderType=cv2.BORDER_REFLECT))
    filtered = filtered[inner]
    height, width, channels = filtered.shape
    rows, cols = height // PATCH, width // PATCH
    cut = filtered[: rows * PATCH, : cols * PATCH].reshape(rows, PATCH, cols, PATCH, channels)
    mad = np.median(cut.transpose(0, 2, 1, 3, 4).reshape(rows, cols, -1, channels), axis=2)
    return (mad / (0.6745 * 6.0)) ** 2


def fit(left: np.ndarray, right: np.ndarray, params: PSFParams, margin: int = 24) -> dict:
    """Per block ``(rows, cols, C)``: radius ``r``, signed ratio ``a`` and share ``rel``."""
    height, width = left.shape[:2]
    inner = (slice(margin, height - margin), slice(margin, width - margin))
    noise = block_noise_variance(left - right, inner) * PATCH * PATCH
    smooth = None
    if SMOOTH > 0:  # noise powers below take the low-pass into account through the kernels
        size = 2 * int(np.ceil(3 * SMOOTH)) + 1
        smooth = cv2.getGaussianKernel(size, SMOOTH).astype(np.float32)
        smooth = smooth @ smooth.T
        left, right = (cv2.filter2D(v, -1, smooth, borderType=cv2.BORDER_REFLECT)
                       for v in (left, right))
    best: dict | None = None
    moments: list = []
    for radius in RADII:
        h_l, h_r = view_kernels(radius, params)
        g_l, g_r = h_l, h_r
        if smooth is not None:
            from scipy.signal import convolve2d

            g_l, g_r = (convolve2d(h, smooth) for h in (h_l, h_r))
        blur = lambda x, k: cv2.filter2D(x, -1, k, borderType=cv2.BORDER_REFLECT)[inner]  # noqa: E731
        l_hl, l_hr = blur(left, h_l), blur(left, h_r)
        r_hl, r_hr = blur(right, h_l), blur(right, h_r)
        p, q = ((l_hr - r_hl) + (l_hl - r_hr)) / 2, ((l_hr - r_hl) - (l_hl - r_hr)) / 2
        pp, pq, qq = (block_sums(x, PATCH, np.float64) for x in (p * p, p * q, q * q))
        noise_p = noise * float((((g_l + g_r) / 2) ** 2).sum())
        noise_q = noise / 4 * float(((g_l - g_r) ** 2).sum())
        informative = (pp > 2 * noise_p) & (qq > 2 * noise_q)
        pp, qq = np.maximum(pp - noise_p, 1e-30), np.maximum(qq - noise_q, 1e-30)
        moments.append((pp, pq, qq, informative))
        ratio = np.clip(-pq / qq, -1.5, 1.5)
        share = np.where(informative, np.clip(1.0 - pq * pq / (pp * qq), 0.0, 1.0), 1.0)
        if best is None:
            best = {"rel": share, "r": np.full(share.shape, radius), "a": ratio}
            continue
        better = share < best["rel"]
        best = {"rel": np.where(better, share, best["rel"]),
                "r": np.where(better, radius, best["r"]), "a": np.where(better, ratio, best["a"])}
    best["moments"] = moments
    return best


def pooled(moments: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's constants pooled over blocks (the log's next lever): green's ratio ``a_g``
    from a grid, each block's radius the one that best explains green at ``a_g`` (the same
    ``a_g`` for all blocks, both signs: behind and in front of the focus), the ``a_g`` of least
    total share over the informative blocks; then red's and blue's ratios by least squares over
    those blocks at those radii. Returns the three ratios, the radii and the usable mask."""
    pp, pq, qq, informative = (np.stack([m[k] for m in moments]) for k in range(4))
    best_total, chosen = np.inf, None
    for a in np.arange(0.3, 1.21, 0.01):
        # signed ratio: a block behind the focus takes +a, in front -a (the lower share)
        shares = [(pp + 2 * sign * a * pq + a * a * qq) / pp for sign in (1.0, -1.0)]
        share = np.minimum(*shares)[..., 1]
        share = np.where(informative[..., 1], share, np.inf)
        index = share.argmin(axis=0)
        least = np.take_along_axis(share, index[None], 0)[0]
        usable = np.isfinite(least) & (least < 0.5)
        total = least[usable].sum() + 0.5 * (~usable).sum()  # unexplained blocks cost a half
        if total < best_total:
            best_total, chosen = total, (a, index, usable)
    a, index, usable = chosen
    picked = [np.take_along_axis(x, index[None, ..., None], 0)[0] for x in (pq, qq)]
    sign = -np.sign(picked[0][..., 1])
    ratios = [a if c == 1 else float(-(sign * picked[0][..., c])[usable].sum()
                                      / picked[1][..., c][usable].sum()) for c in range(3)]
    return np.array(ratios), RADII[index], usable


def main(photo: str, mode: str) -> None:
    image = cv2.resize(read_rgb(PHOTOS / photo), (840, 560), interpolation=cv2.INTER_AREA)
    ys, xs = np.mgrid[0:560, 0:840]
    depth = (1.0 + 6.0 * (xs / 840) ** 1.5 + 0.5 * np.sin(ys / 60)).astype(np.float32)
    frame = dualpixel.synthesize(image, depth, camera="canon-840-linear", seed=1,
                                 distortion=False, noise=mode == "noise")
    left, right = (srgb_to_linear_array(np.asarray(frame[k], np.float32)).astype(np.float32)
                   for k in ("left", "right"))
    truth = block_sums(np.abs(np.asarray(frame["defocus"]))[24:-24, 24:-24], PATCH,
                       np.float64) / PATCH**2
    best = fit(left, right, PSFParams(n=3, alpha=0.45, beta=0.2, kappa=0.21))
    if os.environ.get("POOLED"):
        ratios, radii, usable = pooled(best["moments"])
        error = radii[usable] - truth[usable]
        print(f"{photo} ({mode}, pooled): {int(usable.sum())} usable blocks; ratios "
              f"{np.round(ratios, 3)} (camera 0.70 / 0.92 / 0.94); radius error median "
              f"{np.median(error):+.2f} px, |error| p50 {np.percentile(np.abs(error), 50):.2f} "
              f"p90 {np.percentile(np.abs(error), 90):.2f}")
        return
    usable = (best["r"][..., 1] >= 1.5) & (best["r"][..., 1] < 11.9) & (best["rel"].max(-1) < 0.5)
    oriented = best["a"] * np.sign(best["a"][..., 1:2])
    error = best["r"][..., 1][usable] - truth[usable]
    print(f"{photo} ({mode}): {int(usable.sum())} usable blocks; ratios "
          f"{np.round(np.median(oriented[usable], axis=0), 3)} (camera 0.70 / 0.92 / 0.94); "
          f"radius error median {np.median(error):+.2f} px, |error| p50 "
          f"{np.percentile(np.abs(error), 50):.2f} p90 {np.percentile(np.abs(error), 90):.2f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "budgie_canyon_wren.jpg",
         sys.argv[2] if len(sys.argv) > 2 else "noise")
