"""Issue #77 item 3: the dev scenes rendered by our formation at their own fitted blur, beside
the real views: where does the default model lose more on the real views than on ours?

Each dev scene's target (linear light) is blurred by the Canon camera's left and right kernels
at every radius of a grid; per ``--tile``-px tile the radius whose views best match the real
views (sRGB, both views, the tile and a margin) is kept, and the per-radius renders are blended
by the smoothed tile choice: our formation with the scene's own blur map, its views 8-bit. The
default model deblurs both; per tile (textured ones) its gain over the views' mean, by the
tile's radius and side of the frame, on real and on our views, with the published DPDNet
output's gain beside (``--toned``, ``--registered``: each image's tone and sub-pixel position
matched to the target per tile first, so the f/22 target's other exposure and registration
count against no one). ``--target-aperture RATIO`` adds columns for both outputs blurred, per
tile, by the camera's combined kernel at ``RATIO`` times the tile's radius (4/22 = 0.18: the
DPDD targets are f/22 captures of views taken at f/4, so a target keeps that much of the
views' defocus): how much of the gap is the target's own depth of field. ``--wiener LAMBDA``
adds columns for a linear oracle instead of the network: both views deconvolved jointly with
the camera's left and right kernels at each tile's fitted radius (Wiener, a gradient prior of
weight ``LAMBDA``, linear light), on the real views and on ours: whether the real views are
our kernels' blur as far as a linear inverse can tell; and what no sharp image blurred by the
kernel pair explains (the least over ``--ratio-scales`` times the camera's disparity ratio),
over the views' detail finer than 4 px (target-free), beside what the target blurred by the
pair leaves (tone and sub-pixel shift fitted per tile), and the same with each tile's radius
free (one for all channels, or one per channel: a lens's longitudinal colour). ``--swap`` adds
columns for views rebuilt from the real views' sum and our views' difference and the other way
round: which half of the real views (their image, or the disparity the network reads from their
difference) costs the model its gain; ``--rescale P0 P2`` adds columns for both pairs with their
difference divided by ``P0 - P2 x^2`` (``formation_difference_scale.py``): what reading a
disparity ratio that falls across the frame is worth per tile. Our views can
be coded as the dev views were (``--coded``: the 840-px GIF frames' own palettes; ``--h264
CRF``: an H.264 animation, as the 1620-px views), and their disparity ratio can change across
the frame (``--ratio-profile``). Any folder of the same layout can stand in for the dev scenes, e.g.
frames of our full formation written so (their target as ``dpdnet.png``).

    python experiments/scripts/formation_radius_map.py ../shared/data/canon-dp-real \
        --coded --toned --registered
    python experiments/scripts/formation_radius_map.py ../shared/data/canon-dp-real-hd \
        --camera canon-hd-linear --max-radius 20 --tile 64 --margin 16 --toned --registered \
        [--h264 23] [--ratio-profile 1.234 0.572]

``--disparity`` measures instead how far apart the real views lie against ours (per textured
tile blurred by at least a quarter of ``--max-radius``: the best horizontal shift of one view
onto the other), by the tile's place across the frame. ``--bands`` measures instead, per blur
bin, how the real views' detail energy compares with ours in octave bands (:data:`BANDS`):
whether our blur at the fitted radius removes as much of each scale as the real optics; and how
well our views' sum and difference (detail of 1-8 px) correlate with the real views', and
the real difference's energy over ours.
"""

from __future__ import annotations

import argparse
import glob
import itertools
import os
from pathlib import Path

import cv2
import numpy as np
import torch
from coded_views import code  # this folder's GIF and JPEG round trips
from formation_difference_scale import difference_scaled, halves  # this folder's
from formation_tone_curve import power_curve  # this folder's
from PIL import Image

import dualpixel
from dualpixel.calibration.camera import view_kernels
from dualpixel.io.images import read_rgb, write_png
from dualpixel.optics.camera import load_camera
from dualpixel.optics.crosstalk import apply_crosstalk
from dualpixel.optics.psf import dp_psf
from dualpixel.optics.tone import linear_to_srgb_array, srgb_to_linear_array
from dualpixel.synthesis.view_coding import h264_round_trip

BINS = ((0.0, 2.0), (2.0, 4.5), (4.5, 9.0), (9.0, 20.1))
#: ``--bands``: the detail between Gaussians of these stds (px; 0: the image itself).
BANDS = (0.0, 1.0, 2.0, 4.0, 8.0)


def renders(target: np.ndarray, radii: np.ndarray, camera: str,
            profile: tuple[float, float] = (1.0, 0.0),
            tone: tuple[float, float] | None = None) -> np.ndarray:
    """``(len(radii), 2, H, W, C)`` left and right views (sRGB, 8-bit levels kept as floats):
    the camera's kernels and its per-channel disparity ratio, in linear light; the ratio times
    ``profile[0] - profile[1] * x**2`` with ``x`` from -1 (left edge) to 1 (right edge).
    ``tone`` ``(a, b)``: linear light is ``stored ** (a + b * stored)`` instead of sRGB's."""
    decode, encode = (srgb_to_linear_array, linear_to_srgb_array) if tone is None \
        else power_curve(*tone)
    light = decode(target)
    model = load_camera(camera)
    # profile[0] - profile[1] x^2 is the package's falloff f = profile[1] / profile[0] on a ratio
    # scaled by profile[0] (1 - f / 3): the camera's crosstalk, per channel (optics.crosstalk)
    falloff = profile[1] / profile[0]
    ratio = [r * profile[0] * (1 - falloff / 3) for r in model.disparity_ratio]
    out = []
    for radius in radii:
        if radius < 0.5:
            pair = (light, light)
        else:
            left, right = (torch.from_numpy(cv2.filter2D(light, -1, k,
                                                         borderType=cv2.BORDER_REFLECT))
                           .permute(2, 0, 1) for k in view_kernels(radius, model.psf))
            pair = tuple(v.permute(1, 2, 0).numpy()
                         for v in apply_crosstalk(left, right, ratio, falloff))
        out.append([np.round(np.clip(encode(v), 0, 1) * 255) / 255 for v in pair])
    return np.asarray(out, np.float32)


def at_aperture(image: np.ndarray, radii: np.ndarray, choice: np.ndarray, tile: int,
                camera: str, ratio: float) -> np.ndarray:
    """``image`` (sRGB) blurred in linear light by the camera's combined kernel (the mean of
    its left and right kernels: the whole aperture) at ``ratio`` times each tile's fitted
    radius, blended across tiles as :func:`blend` does: what a capture at a ``1 / ratio``
    times smaller aperture, focused alike, would keep of the blur."""
    light = srgb_to_linear_array(np.clip(image, 0, 1))
    psf = load_camera(camera).psf
    out = []
    for radius in radii * ratio:
        if radius < 0.5:
            out.append(light)
            continue
        kernel = dp_psf(float(radius), psf).combined.numpy()
        out.append(cv2.filter2D(light, -1, kernel, borderType=cv2.BORDER_REFLECT))
    return linear_to_srgb_array(blend(np.asarray(out)[:, None], choice, tile, tile / 4)[0])


def pair_kernels(radius: float, camera, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(C, k, k)`` left and right kernels per channel (convolution orientation): the
    camera's kernels at ``radius`` mixed by its per-channel disparity ratio times ``scale``,
    as :func:`renders` forms the views."""
    ratio = [r * scale for r in camera.disparity_ratio]
    left, right = (torch.from_numpy(np.ascontiguousarray(k[::-1, ::-1]))[None]
                   .expand(len(ratio), -1, -1) for k in view_kernels(radius, camera.psf))
    return tuple(k.numpy() for k in apply_crosstalk(left, right, ratio))


def wiener(views: tuple[np.ndarray, np.ndarray], radii: np.ndarray, choice: np.ndarray,
           tile: int, camera: str, weight: float, scales: tuple[float, ...] = (1.0,),
           pad: int = 48) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sharp image (sRGB) whose blur by the camera's left and right kernels best explains
    both ``views`` (sRGB) in linear light, with a gradient prior of ``weight`` (Wiener),
    solved at every radius of ``radii`` and blended by each tile's ``choice``; and
    per pixel the squared residual of that explanation (linear light, mean of views and
    channels), ``(S, H, W)``: with the camera's disparity ratio and that ratio times each of
    ``scales``: what of the views no sharp image blurred by the kernel pair accounts for,
    target-free; and ``(R, T, T', C)`` that residual's mean per radius, tile and channel (the
    camera's ratio), for fits that free each tile's radius."""
    model = load_camera(camera)
    light = [np.pad(srgb_to_linear_array(np.clip(v, 0, 1)), ((pad, pad), (pad, pad), (0, 0)),
                    mode="reflect") for v in views]
    height, width = light[0].shape[:2]
    spectra = [np.fft.rfft2(v, axes=(0, 1)) for v in light]
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.rfftfreq(width)[None, :]
    prior = (4 * np.sin(np.pi * fy) ** 2 + 4 * np.sin(np.pi * fx) ** 2)[..., None]

    def otf(kernel: np.ndarray) -> np.ndarray:
        size = kernel.shape[-1]
        placed = np.zeros((kernel.shape[0], height, width), np.float32)
        placed[:, :size, :size] = kernel
        placed = np.roll(placed, (-(size // 2), -(size // 2)), axis=(1, 2))
        return np.moveaxis(np.fft.rfft2(placed, axes=(1, 2)), 0, -1)

    inner = (slice(pad, -pad), slice(pad, -pad))
    scales = (1.0, *(x for x in scales if x != 1.0))  # the image: the camera's own ratio
    out, residual, free = [], [[] for _ in scales], []
    for radius in radii:
        if radius < 0.5:
            out.append(light[0][inner] / 2 + light[1][inner] / 2)
            per_channel = (light[0][inner] - light[1][inner]) ** 2 / 4
            for rows in residual:
                rows.append(per_channel.mean(axis=-1))
            free.append(tile_means(per_channel, tile))
            continue
        for number, scale in enumerate(scales):
            left, right = (otf(k) for k in pair_kernels(radius, model, scale))
            sharp = ((np.conj(left) * spectra[0] + np.conj(right) * spectra[1])
                     / (np.abs(left) ** 2 + np.abs(right) ** 2 + weight * prior))
            per_channel = sum(
                (np.fft.irfft2(spectrum - kernel * sharp, s=(height, width), axes=(0, 1))[inner])
                ** 2 for spectrum, kernel in zip(spectra, (left, right))) / 2
            residual[number].append(per_channel.mean(axis=-1))
            if number == 0:
                out.append(np.fft.irfft2(sharp, s=(height, width), axes=(0, 1))[inner]
                           .astype(np.float32))
                free.append(tile_means(per_channel, tile))
    # blended sharply: a deconvolution at a neighbour's radius rings where a blur would not
    blended = blend(np.asarray(out)[:, None], choice, tile, tile / 16)[0]
    unexplained = np.stack([blend(np.asarray(rows, np.float32)[:, None, ..., None], choice, tile,
                                  tile / 16)[0, ..., 0] for rows in residual])
    return linear_to_srgb_array(np.clip(blended, 0, 1)), unexplained, np.asarray(free)


def write_dev_scene(folder: Path, views: np.ndarray, target: np.ndarray) -> None:
    """``folder`` laid out as a dev scene, 8-bit: ``views`` ``(2, H, W, C)`` as view0 / view1,
    ``target``, and the target again standing in for the published DPDNet output."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, image in (("view0", views[0]), ("view1", views[1]), ("target", target),
                        ("dpdnet", target)):
        write_png(folder / f"{name}.png", np.clip(image, 0, 1), bit_depth=8)


def tile_place(col: int, tile: int, width: int) -> float:
    """Where the centre of tile column ``col`` lies across a ``width``-px frame: -1 at the left
    edge, 1 at the right."""
    return (col + 0.5) * tile / width * 2 - 1


def tile_means(image: np.ndarray, tile: int) -> np.ndarray:
    """``(rows, cols, C)``: ``image`` ``(H, W, C)`` averaged over each whole ``tile``-px tile."""
    rows, cols = image.shape[0] // tile, image.shape[1] // tile
    return image[: rows * tile, : cols * tile].reshape(rows, tile, cols, tile, -1).mean(axis=(1, 3))


def tile_choice(real: tuple[np.ndarray, np.ndarray], rendered: np.ndarray, tile: int,
                margin: int, channel: int | None = None) -> np.ndarray:
    """Per tile, the index of the radius whose rendered views best match the real ones (in
    every channel, or in ``channel`` alone)."""
    pick = slice(None) if channel is None else slice(channel, channel + 1)
    error = sum(((rendered[:, i, ..., pick] - real[i][None, ..., pick]) ** 2).mean(axis=-1)
                for i in (0, 1))
    size = tile + 2 * margin
    boxed = np.stack([cv2.boxFilter(e, -1, (size, size), borderType=cv2.BORDER_REFLECT)
                      for e in error])
    rows, cols = real[0].shape[0] // tile, real[0].shape[1] // tile
    centres = boxed[:, tile // 2 : rows * tile : tile, tile // 2 : cols * tile : tile]
    return np.argmin(centres, axis=0)


def blend(rendered: np.ndarray, choice: np.ndarray, tile: int, sigma: float) -> np.ndarray:
    """The renders blended per pixel by the smoothed one-hot of each tile's choice."""
    height, width = rendered.shape[2:4]
    weights = []
    for index in range(rendered.shape[0]):
        onehot = np.kron((choice == index).astype(np.float32), np.ones((tile, tile), np.float32))
        onehot = np.pad(onehot, ((0, height - onehot.shape[0]), (0, width - onehot.shape[1])),
                        mode="edge")
        weights.append(cv2.GaussianBlur(onehot, (0, 0), sigma))
    weights = np.asarray(weights)
    weights /= weights.sum(axis=0, keepdims=True)
    return np.einsum("rhw,rvhwc->vhwc", weights, rendered)


def with_palette_of(view: np.ndarray, real: np.ndarray) -> np.ndarray:
    """``view`` (RGB in [0, 1]) coded as a GIF frame with ``real``'s own colours (its palette,
    Floyd-Steinberg dither): the dev views' coding, applied to ours."""
    colours = np.unique((real * 255).round().astype(np.uint8).reshape(-1, 3), axis=0)
    if len(colours) > 256:
        raise SystemExit("--coded: the real views are not GIF frames (more than 256 colours)")
    palette = Image.new("P", (1, 1))
    palette.putpalette(colours.reshape(-1).tolist() + [0] * (768 - colours.size))
    image = Image.fromarray((np.clip(view, 0, 1) * 255).round().astype(np.uint8))
    coded = image.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG)
    return np.asarray(coded.convert("RGB"), np.float32) / 255


def toned(image: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``image`` after the per-channel gain and offset that best match ``target`` (least
    squares): what is left once the f/22 target's other exposure is taken out."""
    out = np.empty_like(image)
    for c in range(image.shape[-1]):
        a = np.stack([image[..., c].ravel(), np.ones(image[..., c].size)], axis=1)
        coef = np.linalg.lstsq(a, target[..., c].ravel(), rcond=None)[0]
        out[..., c] = image[..., c] * coef[0] + coef[1]
    return out


TONED = False
SHIFTS = [(dx, dy) for dx in (-0.5, -0.25, 0.0, 0.25, 0.5) for dy in (-0.5, -0.25, 0.0, 0.25, 0.5)]


def shifted_copies(image: np.ndarray) -> list[np.ndarray]:
    """``image`` moved by each of ``SHIFTS`` (px; bicubic)."""
    height, width = image.shape[:2]
    return [cv2.warpAffine(image, np.float32([[1, 0, dx], [0, 1, dy]]), (width, height),
                           flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
            for dx, dy in SHIFTS]


def best_shift(copies: list[np.ndarray], box: tuple[slice, slice],
               target: np.ndarray) -> np.ndarray:
    """The copy whose ``box`` is closest to ``target[box]``: the tile's local registration."""
    return min((c[box] for c in copies), key=lambda c: float(((c - target[box]) ** 2).mean()))


def toned_residual(image: np.ndarray, view: np.ndarray) -> float:
    """Mean square of what is left of ``view`` once ``image`` is fitted to it by a gain and an
    offset per channel (least squares), over pixels and channels."""
    x, y = image.reshape(-1, image.shape[-1]), view.reshape(-1, view.shape[-1])
    x, y = x - x.mean(axis=0), y - y.mean(axis=0)
    cov = (x * y).mean(axis=0)
    return float(((y**2).mean(axis=0) - cov**2 / ((x**2).mean(axis=0) + 1e-12)).mean())


def jpeg(view: np.ndarray, quality: int) -> np.ndarray:
    """``view`` (RGB in [0, 1]) through JPEG at ``quality`` (a DCT coder like the H.264 of the
    1620-px dev views: small coefficients quantised away)."""
    bgr = (np.clip(view, 0, 1)[..., ::-1] * 255).round().astype(np.uint8)
    return code(np.ascontiguousarray(bgr), f"jpeg{quality}")[..., ::-1].astype(np.float32) / 255


def band_energy(image: np.ndarray, sigma: float = 1.0) -> float:
    """Mean square of ``image``'s detail finer than a Gaussian of ``sigma`` px (grey)."""
    grey = image.mean(axis=-1)
    return float(((grey - cv2.GaussianBlur(grey, (0, 0), sigma)) ** 2).mean()) + 1e-12


def scored_tiles(choice: np.ndarray, radii: np.ndarray, target: np.ndarray, tile: int):
    """``(row, col, box, radius)`` of each tile a blur comparison reads: textured in the
    target (flat tiles say nothing about blur) and fitted at 0.5 px or more (below, our views
    are the target)."""
    for (row, col), index in np.ndenumerate(choice):
        box = (slice(row * tile, row * tile + tile), slice(col * tile, col * tile + tile))
        grey = target[box].mean(axis=-1)
        if (grey - cv2.GaussianBlur(grey, (0, 0), 2)).std() >= 0.01 and radii[index] >= 0.5:
            yield row, col, box, radii[index]


def band_rows_of(views: tuple[np.ndarray, np.ndarray], ours: np.ndarray, target: np.ndarray,
                 choice: np.ndarray, radii: np.ndarray, tile: int) -> list[tuple]:
    """The ``--bands`` rows of one scene (:func:`print_bands`): per scored tile, its radius and
    ``|x|``, the real / our energy per band, and the sum's and difference's relation."""
    real_bands, our_bands = ([octave_bands(v) for v in pair] for pair in (views, ours))
    rows = []
    for _, col, box, radius in scored_tiles(choice, radii, target, tile):
        energy = [[sum((view[k][box] ** 2).mean() for view in bands)
                   for k in range(len(BANDS) - 1)] for bands in (real_bands, our_bands)]
        # the sum and difference of the views' detail of 1-8 px, real against ours
        detail = [[sum(view[k][box] for k in range(1, len(BANDS) - 1)) for view in bands]
                  for bands in (real_bands, our_bands)]
        relation = [np.corrcoef(op(*detail[0]).ravel(), op(*detail[1]).ravel())[0, 1]
                    for op in (np.add, np.subtract)]
        relation.append(float((np.subtract(*detail[0]) ** 2).mean()
                              / ((np.subtract(*detail[1]) ** 2).mean() + 1e-12)))
        rows.append((radius, abs(tile_place(col, tile, target.shape[1])),
                     *(r / o for r, o in zip(*energy)), *relation))
    return rows


def octave_bands(image: np.ndarray) -> list[np.ndarray]:
    """``image``'s grey detail between consecutive Gaussians of :data:`BANDS`."""
    levels = [image.mean(axis=-1)]
    levels += [cv2.GaussianBlur(levels[0], (0, 0), sigma) for sigma in BANDS[1:]]
    return [finer - coarser for finer, coarser in itertools.pairwise(levels)]


def print_bands(rows: list[tuple]) -> None:
    """The ``--bands`` table: per blur bin and side of the frame, the median ratio of the real
    views' energy to ours in each band, and of the correlations of their sums and differences;
    ``rows``: ``(radius, |x|, ratio per band..., sum correlation, difference correlation,
    real / our difference's energy)``."""
    table = np.asarray(rows)
    names = [f"{low:g}-{high:g} px" for low, high in itertools.pairwise(BANDS)]
    names += ["sum, real with ours", "difference, real with ours", "difference's energy"]
    print("\n| fitted radius | tiles | real / our views' detail energy, "
          f"{' | '.join(names)} |\n|---|---|{'---|' * len(names)}")
    for (low, high), (near, far) in itertools.product(BINS, ((0.0, 0.6), (0.6, 1.01))):
        pick = ((table[:, 0] >= low) & (table[:, 0] < high) & (table[:, 1] >= near)
                & (table[:, 1] < far))
        if pick.any():
            print(f"| {low:g}-{high:g} px, |x| {near:g}-{min(far, 1):g} | {pick.sum()} | "
                  + " | ".join(f"{np.median(table[pick, 2 + k]):.2f}" for k in range(len(names)))
                  + " |")


def h264(views: np.ndarray, crf: int, hold: int = 10, loops: int = 3) -> np.ndarray:
    """The two views ``(2, H, W, 3)`` in [0, 1] coded as the 1620-px dev views were: an H.264
    animation showing each view ``hold`` frames, looped; each view back as the mean of its frames
    after the first loop (:func:`dualpixel.synthesis.view_coding.h264_round_trip`)."""
    frames = (np.clip(views, 0, 1) * 255).round().astype(np.uint8)
    return h264_round_trip(frames, crf, hold=hold, loops=loops) / 255


def tile_disparity(left: np.ndarray, right: np.ndarray, tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Per tile: the horizontal shift (px, 0.25 steps) that best moves ``right`` onto ``left``,
    and the squared error it leaves as a share of the unshifted one (low: a clear match)."""
    a, b = left.mean(axis=-1).astype(np.float32), right.mean(axis=-1).astype(np.float32)
    shifts = np.arange(-10, 10.01, 0.25)
    errors = []
    for dx in shifts:
        moved = cv2.warpAffine(b, np.float32([[1, 0, dx], [0, 1, 0]]), b.shape[::-1],
                               flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        errors.append(cv2.boxFilter((a - moved) ** 2, -1, (tile, tile))[tile // 2 :: tile,
                                                                          tile // 2 :: tile])
    errors = np.asarray(errors)
    return shifts[errors.argmin(axis=0)], errors.min(axis=0) / (errors[len(shifts) // 2] + 1e-12)


def disparity_across(rows: list[tuple[float, ...]]) -> None:
    """Print the real views' disparity over ours by the tile's place across the frame, and the
    fit ``ratio = p0 - p2 x**2`` (``x`` -1 at the left edge, 1 at the right)."""
    across, ratio = np.asarray(rows).T
    print("\n| across the frame (x) | tiles | real / our views' disparity (median) |")
    print("|---|---|---|")
    for low in (-1.0, -0.6, -0.2, 0.2, 0.6):
        pick = (across >= low) & (across < low + 0.4 + 1e-6)
        print(f"| {low:+.1f} to {low + 0.4:+.1f} | {pick.sum()} | {np.median(ratio[pick]):.2f} |")
    design = np.stack([np.ones_like(across), -across**2], axis=1)
    p0, p2 = np.linalg.lstsq(design, ratio, rcond=None)[0]
    spread = np.median(np.abs(ratio - design @ [p0, p2]))
    print(f"fit: {p0:.3f} - {p2:.3f} x^2 (median absolute residual {spread:.3f}); "
          f"--ratio-profile {p0:.3f} {p2:.3f}")


def swapped(real: tuple[np.ndarray, np.ndarray], ours: np.ndarray
            ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``--swap``: the views rebuilt from one pair's sum and the other's difference, (L + R) / 2
    +- (L - R) / 2, clipped to [0, 1]: the real sum with our difference, then ours with the real
    difference. Which half of the views costs the model its gain on the real ones."""
    (real_sum, real_difference), (our_sum, our_difference) = halves(*real), halves(*ours)
    return [(np.clip(total + difference, 0, 1), np.clip(total - difference, 0, 1))
            for total, difference in ((real_sum, our_difference), (our_sum, real_difference))]


def gain(output: np.ndarray, reference: np.ndarray, target: np.ndarray) -> float:
    """Gain of ``output`` over ``reference`` against ``target`` (dB); both toned first with
    ``--toned``."""
    if TONED:
        output, reference = toned(output, target), toned(reference, target)
    return 10 * np.log10(((reference - target) ** 2).mean() / ((output - target) ** 2).mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", help="a folder of dev scenes: view0, view1, target, dpdnet")
    parser.add_argument("--model", default="rdpd-light")
    parser.add_argument("--camera", default="canon-840-linear")
    parser.add_argument("--max-radius", type=float, default=10.0,
                        help="the largest CoC radius fitted, px (20 for 1620-px views)")
    parser.add_argument("--tile", type=int, default=32)
    parser.add_argument("--margin", type=int, default=8)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--coded", action="store_true",
                        help="code our views with the real views' GIF palettes")
    parser.add_argument("--ratio-profile", type=float, nargs=2, default=(1.0, 0.0),
                        metavar=("P0", "P2"), help="disparity ratio times P0 - P2 x^2 across "
                        "the frame (x from -1 to 1)")
    parser.add_argument("--disparity", action="store_true",
                        help="only measure the views' disparity against ours across the frame")
    parser.add_argument("--bands", action="store_true",
                        help="only compare the views' detail energy with ours in octave bands")
    parser.add_argument("--h264", type=int, default=0, metavar="CRF",
                        help="code our views as an H.264 animation at CRF (needs PyAV)")
    parser.add_argument("--jpeg", type=int, default=0, metavar="QUALITY",
                        help="code our views as JPEG at QUALITY")
    parser.add_argument("--scenes", type=int, nargs="*", help="only these scene numbers")
    parser.add_argument("--per-channel", action="store_true",
                        help="fit and render each colour channel's blur on its own")
    parser.add_argument("--registered", action="store_true",
                        help="per tile, move each image by its best sub-pixel shift first")
    parser.add_argument("--target-aperture", type=float, default=0.0, metavar="RATIO",
                        help="also score the outputs blurred at RATIO times each tile's radius")
    parser.add_argument("--wiener", type=float, default=0.0, metavar="LAMBDA",
                        help="also score a Wiener deconvolution of both views per tile")
    parser.add_argument("--ratio-scales", type=float, nargs="+", default=[1.0],
                        help="with --wiener: the unexplained share is the least over the "
                        "disparity ratio times each of these, per tile")
    parser.add_argument("--swap", action="store_true",
                        help="also score views with the real views' sum and our views' "
                        "difference, and ours' sum with the real difference")
    parser.add_argument("--rescale", type=float, nargs=2, metavar=("P0", "P2"),
                        help="also score both pairs with their difference divided by P0 - P2 "
                        "x^2 (x from -1 to 1 across the frame)")
    parser.add_argument("--toned", action="store_true",
                        help="per tile, match each image's tone to the target before scoring")
    parser.add_argument("--tone", type=float, nargs=2, metavar=("A", "B"),
                        help="render our views in the light stored ** (A + B stored) instead "
                        "of sRGB-linear")
    parser.add_argument("--save", metavar="DIR",
                        help="only write our views at the fitted blur (coded as asked) as dev "
                        "scenes under DIR, the target standing in for DPDNet's output")
    args = parser.parse_args()
    global TONED
    TONED = args.toned
    torch.set_num_threads(args.threads)
    radii = np.concatenate([[0.0], np.arange(0.75, 10.01, 0.25),
                            np.arange(10.5, args.max_radius + 0.01, 0.5)])
    rows = []  # radius, real gain, ours gain, dpdnet gain, scene, detail ratio, |x|
    disparities = []  # x across the frame, real / our disparity
    band_rows = []  # --bands: band_rows_of's rows
    for number, scene in enumerate(sorted(glob.glob(os.path.join(args.root, "scene_*")))):
        if args.scenes and number not in args.scenes:
            continue
        coding = float("inf")
        left, right, target, published = (read_rgb(os.path.join(scene, f"{n}.png"))
                                          for n in ("view0", "view1", "target", "dpdnet"))
        rendered = renders(target, radii, args.camera, tuple(args.ratio_profile),
                           None if args.tone is None else tuple(args.tone))
        choice = tile_choice((left, right), rendered, args.tile, args.margin)
        if args.per_channel:
            ours = np.concatenate([
                blend(rendered[..., c : c + 1],
                      tile_choice((left, right), rendered, args.tile, args.margin, c),
                      args.tile, args.tile / 4) for c in range(3)], axis=-1)
        else:
            ours = blend(rendered, choice, args.tile, args.tile / 4)
        if args.coded:
            ours = np.stack([with_palette_of(o, r) for o, r in zip(ours, (left, right))])
        if args.jpeg or args.h264:
            clean = ours
            ours = (h264(ours, args.h264) if args.h264
                    else np.stack([jpeg(o, args.jpeg) for o in ours]))
            coding = 10 * np.log10(1 / ((ours - clean) ** 2).mean())
        if args.save:
            out = Path(args.save) / os.path.basename(scene)
            write_dev_scene(out, ours, target)
            print(f"{out}: our views at the fitted blur, coding {coding:.1f} dB", flush=True)
            continue
        if args.disparity:
            grey = target.mean(axis=-1)
            detail = cv2.boxFilter((grey - cv2.GaussianBlur(grey, (0, 0), 2)) ** 2, -1,
                                   (args.tile, args.tile))[args.tile // 2 :: args.tile,
                                                           args.tile // 2 :: args.tile]
            (real, real_fit), (mine, my_fit) = (tile_disparity(*pair, args.tile)
                                                for pair in ((left, right), ours))
            for (row, col), index in np.ndenumerate(choice):
                if (row < real.shape[0] and col < real.shape[1] and detail[row, col] > 1e-4
                        and radii[index] >= args.max_radius / 4 and abs(mine[row, col]) > 0.5
                        and real_fit[row, col] < 0.6 and my_fit[row, col] < 0.6):
                    disparities.append((tile_place(col, args.tile, target.shape[1]),
                                        real[row, col] / mine[row, col]))
            continue
        if args.bands:
            band_rows += band_rows_of((left, right), ours, target, choice, radii, args.tile)
            print(os.path.basename(scene), flush=True)
            continue
        real_out = dualpixel.deblur(left, right, model=args.model, device="cpu")
        ours_out = dualpixel.deblur(ours[0], ours[1], model=args.model, device="cpu")
        real_in, ours_in = (left + right) / 2, (ours[0] + ours[1]) / 2
        images = [real_out, real_in, ours_out, ours_in, published]
        if args.target_aperture:
            images += [at_aperture(o, radii, choice, args.tile, args.camera, args.target_aperture)
                       for o in (real_out, ours_out)]
        unexplained = []
        if args.wiener:
            for pair in ((left, right), ours):
                image, residual, free = wiener(pair, radii, choice, args.tile, args.camera,
                                               args.wiener, tuple(args.ratio_scales))
                # the views' detail finer than 4 px (linear light): what a deconvolution acts on
                detail = np.mean([((v - cv2.GaussianBlur(v, (0, 0), 4)) ** 2).mean(axis=-1)
                                  for v in (srgb_to_linear_array(np.clip(w, 0, 1))
                                            for w in pair)], axis=0)
                images.append(image)
                unexplained.append((residual, detail, free))
            # the target blurred by the pair (our views, uncoded), against the real views
            our_copies = [shifted_copies(srgb_to_linear_array(np.clip(v, 0, 1)))
                          for v in (clean if args.jpeg or args.h264 else ours)]
            real_linear = [srgb_to_linear_array(np.clip(v, 0, 1)) for v in (left, right)]
        if args.swap:
            images += [dualpixel.deblur(*views, model=args.model, device="cpu")
                       for views in swapped((left, right), ours)]
        if args.rescale:
            images += [dualpixel.deblur(*difference_scaled(*views, tuple(args.rescale)),
                                        model=args.model, device="cpu")
                       for views in ((left, right), ours)]
        copies = [shifted_copies(i) if args.registered else [i] for i in images]
        t = args.tile
        for row, col, box, radius in scored_tiles(choice, radii, target, t):
            ro, ri, oo, oi, po, *apertured = (best_shift(c, box, target) for c in copies)
            bands = [band_energy(v[box]) for v in (left, ours[0])]
            rows.append((radius, gain(ro, ri, target[box]), gain(oo, oi, target[box]),
                         gain(po, ri, target[box]), number, bands[0] / bands[1],
                         abs(tile_place(col, t, target.shape[1])),
                         *(gain(a, i, target[box])
                           for a, i in zip(apertured, itertools.cycle((ri, oi)))),
                         *(residual[:, box[0], box[1]].mean(axis=(1, 2)).min()
                           / detail[box].mean() for residual, detail, _ in unexplained),
                         *([np.mean([min(toned_residual(c[box], view[box]) for c in shifted)
                                     for shifted, view in zip(our_copies, real_linear)])
                            / unexplained[0][1][box].mean()] if args.wiener else []),
                         # each tile's radius free: one for all channels, one per channel
                         *(value / detail[box].mean() for _, detail, free in unexplained
                           for value in (free[:, row, col].mean(axis=-1).min(),
                                         free[:, row, col].min(axis=0).mean()))))
        whole = [gain(o, i, target) for o, i in ((real_out, real_in), (ours_out, ours_in))]
        print(f"{os.path.basename(scene)}: whole-frame gain real {whole[0]:+.2f}, ours "
              f"{whole[1]:+.2f} dB; views' match rms "
              f"{np.sqrt(((ours - np.stack([left, right])) ** 2).mean()) * 255:.2f} levels; "
              f"our views' coding {coding:.1f} dB",
              flush=True)
    if args.save:
        return
    if args.disparity:
        disparity_across(disparities)
        return
    if args.bands:
        print_bands(band_rows)
        return
    table = np.asarray(rows)
    # the optional columns, in the order the rows hold them: (heading, format)
    columns = [(f"{who}, output at {args.target_aperture:g} r", "+.2f")
               for who in ("real views", "ours")] if args.target_aperture else []
    if args.wiener:
        columns += [(f"{who}, Wiener", "+.2f") for who in ("real views", "ours")]
    if args.swap:
        columns += [("real sum, our difference", "+.2f"), ("our sum, real difference", "+.2f")]
    if args.rescale:
        columns += [(f"{who}, difference / r(x)", "+.2f") for who in ("real views", "ours")]
    if args.wiener:
        columns += [(f"{who} unexplained / detail", ".4f") for who in ("real views", "ours")]
        columns += [("real views, by the target and pair", ".4f")]
        columns += [(f"{who}, radius free{each}", ".4f") for who in ("real views", "ours")
                    for each in ("", " per channel")]
    print("\n| fitted radius | tiles | real views | ours at the fitted blur | DPDNet (published) "
          "| real / our views' fine detail (median) |"
          + "".join(f" {heading} |" for heading, _ in columns))
    print("|---|---|---|---|---|---|" + "---|" * len(columns))
    for (low, high), (near, far) in itertools.product(BINS, ((0.0, 0.6), (0.6, 1.01))):
        pick = ((table[:, 0] >= low) & (table[:, 0] < high) & (table[:, 6] >= near)
                & (table[:, 6] < far))
        if pick.any():
            print(f"| {low:g}-{high:g} px, |x| {near:g}-{min(far, 1):g} | {pick.sum()} | "
                  f"{table[pick, 1].mean():+.2f} | {table[pick, 2].mean():+.2f} | "
                  f"{table[pick, 3].mean():+.2f} | "
                  f"{np.median(table[pick, 5]):.2f} |"
                  + "".join(f" {table[pick, k].mean():{form}} |"
                            for k, (_, form) in enumerate(columns, start=7)))


if __name__ == "__main__":
    main()
