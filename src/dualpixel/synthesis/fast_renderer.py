"""The default ("fast") layered renderer: the reference's layers and compositing,
with large blur rendered at reduced resolution and cheap convolutions.

The reference (``render_dp_views(..., mode="exact")``) splits the CoC range into up to 500 equal
layers and convolves each at full resolution. This renderer keeps the same layers (near focus
exactly; where the blur is large, runs of them 1 % of the blur wide, see
:func:`dualpixel.synthesis.layers.quantise_layers`) and the same back-to-front, normalised
compositing (Eq. 7), and saves work three ways:

1. **Large blur at reduced resolution.** A layer blurred by ``|r| >= d * R_LOW`` px holds no
   detail beyond its blur's bandwidth at 1/d resolution (d a power of two; d = 2 already from
   ``2 * R_LOW_HALF``): its premultiplied planes ``[I m, m]`` are area-averaged by d, convolved
   with the PSF of radius ``r / d`` (the PSF model is scale covariant), composited with the
   other layers of the same d at that resolution, and the group's colour and coverage are
   upsampled (bicubic) and composited over the full-resolution result, only over the blocks the
   group covers. Premultiplied "over" is associative, so grouping changes nothing but the
   resampling.
2. **Cheap convolutions.** On the CPU, OpenCV's ``filter2D`` on height x width x 4 planes (colour
   and mask together); kernels above :data:`CV_MAX_KERNEL` in bands of kernel rows, applied to
   bands of image rows as wide as the layer's pixels there; torch alone on other devices.
3. **Batched, trimmed PSFs.** One :func:`dualpixel.optics.dp_psf` call per kernel size, on the
   CPU whatever device renders; outer rings holding less than :data:`TRIM_MASS` are dropped.

Measured on a 1920x1080 dead-leaves frame (``benchmarks/bench_synthesis.py``, docs/benchmarks.md):
>= 48.5 dB against exact for set0..set4 on left, right and combined, in 0.04-0.07 of the time of
a baseline after the authors' algorithm.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch
import torch.nn.functional as F

from dualpixel.optics.psf import PSFModel, PSFParams, dp_psf, dp_psf_each, kernel_size
from dualpixel.synthesis.convolution import convolve_same
from dualpixel.synthesis.layers import bounding_boxes, grown_box, quantise_layers, row_extents

__all__ = ["CV_MAX_KERNEL", "MAX_DOWNSAMPLE", "R_LOW", "R_LOW_HALF", "STRIP_ROWS", "TRIM_MASS",
           "crop_margin", "downsample_factor", "render_fast"]

#: A layer is rendered at 1/d resolution (d a power of two) when its |r| is at least
#: ``d * R_LOW`` px (``2 * R_LOW_HALF`` for d = 2), so its blur is still that large there.
#: Measured (set0..set4, 1920x1080, bicubic): 3 / 2 gave >= 48.5 dB against exact; 2 / 2 fell to
#: 44.4 dB on set4; bilinear upsampling cost 1-3 dB.
R_LOW = 3.0
R_LOW_HALF = 2.0
MAX_DOWNSAMPLE = 16


def downsample_factor(radius: float) -> int:
    """Largest power of two d <= :data:`MAX_DOWNSAMPLE` with ``|radius| >= d * R_LOW``; d = 2
    already from ``|radius| >= 2 * R_LOW_HALF``."""
    d = 1
    while d * 2 <= MAX_DOWNSAMPLE and abs(radius) >= d * 2 * (R_LOW_HALF if d == 1 else R_LOW):
        d *= 2
    return d


def layer_kernels(groups: list[tuple[int, list[float], PSFParams | None, PSFModel]],
                  dtype: torch.dtype) -> list[list[torch.Tensor]]:
    """Per group ``(d, radii, params, model)`` (CoC radii in px at full resolution, the group's
    PSF shape and model), its ``(2 views, S, S)`` kernels at 1/d resolution, each view summing
    to 1: one batched PSF call per model and kernel size over all the groups (each radius keeps
    its own size and shape), so the layers of many groups and frames cost one. Made on the CPU
    whatever device renders: a few hundred small tensors, each step of which would be a
    kernel launch on an accelerator (and each trimming test a synchronisation); the caller
    moves them to its device."""
    radii = [r / d for d, group, _, _ in groups for r in group]
    shapes = [p or PSFParams() for _, group, p, _ in groups for _ in group]
    models = [m for _, group, _, m in groups for _ in group]
    sizes = [kernel_size(r, m, p.kappa) for r, p, m in zip(radii, shapes, models)]
    kernels: list[torch.Tensor] = [torch.empty(0, dtype=dtype)] * len(radii)
    batches: dict[tuple[str, int], list[int]] = {}
    for i, key in enumerate(zip(models, sizes)):
        batches.setdefault(key, []).append(i)
    for (model, size), members in sorted(batches.items()):
        batch = torch.tensor([radii[i] for i in members], dtype=dtype)
        if model == "ours":
            left, right = dp_psf_each(batch, [shapes[i] for i in members], size)
        else:  # the baselines have no shape parameters
            left, right = dp_psf(batch, model=model, size=size)
        both = 2.0 * torch.stack((left, right), dim=1)
        for i, kernel in zip(members, _trimmed(both)):
            kernels[i] = kernel
    tables, start = [], 0
    for _, group, _, _ in groups:
        tables.append(kernels[start : start + len(group)])
        start += len(group)
    return tables


def _trimmed(kernels: torch.Tensor) -> list[torch.Tensor]:
    """``(K, 2, S, S)`` kernels, each without the outer rings that hold less than
    :data:`TRIM_MASS` of either view, counted from the outside in up to the first that holds
    more (the support's safety margin: 3 sigma of the smoothing plus a pixel): K ``(2, s, s)``
    views of the input."""
    size = kernels.shape[-1]
    half = size // 2
    inside = torch.stack([kernels[..., j : size - j, j : size - j].sum(dim=(-2, -1))
                          for j in range(half + 1)], dim=-1)  # (K, 2, half + 1)
    rings = (inside[..., :-1] - inside[..., 1:]).abs().amax(dim=1)  # (K, half), outermost first
    kept = rings >= TRIM_MASS
    drop = torch.where(kept.any(dim=1), kept.int().argmax(dim=1), half).tolist()
    return [k[:, j : size - j, j : size - j] for k, j in zip(kernels, drop)]


#: Largest square kernel OpenCV's ``filter2D`` convolves directly (from 13 x 13 it switches to
#: its DFT path: 60-68 ms on 4 x 300x1920 planes at S = 13-31 against 18 ms directly at S = 11).
#: Larger kernels are split into bands of rows, each convolved directly, and summed.
#: Direct convolution gives the same bytes with any number of threads, unlike torch's FFT
#: (measured: its inverse transform changes in the last bit between 1 and 2 threads), so a
#: dataset does not depend on how many workers rendered it.
CV_MAX_KERNEL = 11
#: Kernel rings dropped while they hold less than this of a view's mass: ``kernel_size`` leaves
#: 3 sigma of the smoothing and a pixel of margin. Measured on set0..set4 at 1920x1080: the
#: same PSNR against exact to 0.1 dB with 2e-4 or 1e-3, and half the time for set2..set4.
TRIM_MASS = 2e-4
#: OpenCV filters float32 directly while the kernel has fewer than 130 taps (its DFT threshold).
CV_MAX_TAPS = 129


def _filter2d(source, kernel, target, height: int, width: int) -> None:
    """``target`` = ``source`` ``(h + S - 1, w + S - 1, P)`` (zero-padded by S // 2) correlated
    with ``kernel`` ``(S, S)``, in bands of whole kernel rows with at most :data:`CV_MAX_TAPS`
    taps each (so every band is filtered directly)."""
    size = kernel.shape[0]
    rows = max(1, CV_MAX_TAPS // size)
    target[...] = 0.0
    for i0 in range(0, size, rows):
        band = np.ascontiguousarray(kernel[i0:i0 + rows])
        part = cv2.filter2D(source, -1, band, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
        part = part[..., None] if part.ndim == 2 else part
        target += part[i0:i0 + height, :width]


def _convolve(planes: torch.Tensor, kernels: torch.Tensor) -> torch.Tensor:
    """Convolve ``(h, w, P)`` planes (P <= 4) with ``(K, S, S)`` kernels: ``(K, h, w, P)``.

    True convolution with zero padding, output the size of the input, kernel centre S // 2.
    """
    size = kernels.shape[-1]
    if planes.device.type != "cpu" or planes.dtype != torch.float32:
        kernels = kernels.to(planes.device, planes.dtype, non_blocking=True)
        return convolve_same(planes.permute(2, 0, 1), kernels).permute(0, 2, 3, 1)
    source = planes.contiguous().numpy()
    out = torch.empty((kernels.shape[0], *planes.shape), dtype=planes.dtype)
    flipped = torch.flip(kernels, dims=(-2, -1)).contiguous().numpy()  # filter2D correlates
    if size <= CV_MAX_KERNEL:
        for kernel, target in zip(flipped, out.numpy()):
            cv2.filter2D(source, -1, kernel, dst=target, borderType=cv2.BORDER_CONSTANT)
        return out
    half = size // 2
    padded = cv2.copyMakeBorder(source, half, half, half, half, cv2.BORDER_CONSTANT, value=0)
    padded = padded[..., None] if padded.ndim == 2 else padded
    for kernel, target in zip(flipped, out.numpy()):
        _filter2d(padded, kernel, target, *planes.shape[:2])
    return out


def _upsample(layer: torch.Tensor, d: int) -> torch.Tensor:
    """Bicubic upsampling of ``(views, h, w, P)`` by ``d`` (pixel centres aligned, as area
    averaging left them): OpenCV's ``resize`` on the CPU (10x faster than torch's here),
    torch's ``interpolate`` elsewhere; both use the a = -0.75 cubic and replicate the border."""
    if layer.device.type == "cpu" and layer.dtype == torch.float32 and layer.shape[-1] <= 4:
        views, height, width, planes = layer.shape
        out = torch.empty(views, height * d, width * d, planes, dtype=layer.dtype)
        for view, target in zip(layer, out.numpy()):
            cv2.resize(view.contiguous().numpy(), (width * d, height * d), dst=target,
                       interpolation=cv2.INTER_CUBIC)
        return out
    return F.interpolate(layer.permute(0, 3, 1, 2), scale_factor=d, mode="bicubic",
                         align_corners=False).permute(0, 2, 3, 1)


def _covered_regions(alpha: torch.Tensor, gap: int = 8) -> list[tuple[int, int, int, int]]:
    """Half-open (row0, row1, col0, col1) boxes of ``alpha`` ``(views, h, w, 1)`` > 0: runs of
    covered rows (split at ``gap`` or more empty rows), each with its covered columns."""
    covered = (alpha > 0).any(dim=0)[..., 0]  # (h, w)
    rows = torch.nonzero(covered.any(dim=1))[:, 0].tolist()
    regions: list[tuple[int, int, int, int]] = []
    start = 0
    for k in range(1, len(rows) + 1):
        if k == len(rows) or rows[k] - rows[k - 1] > gap:
            row0, row1 = rows[start], rows[k - 1] + 1
            cols = torch.nonzero(covered[row0:row1].any(dim=0))[:, 0]
            regions.append((row0, row1, int(cols[0]), int(cols[-1]) + 1))
            start = k
    return regions


def _over(colour: torch.Tensor, layer: torch.Tensor, channels: int) -> None:
    """Composite a premultiplied ``layer`` ``(views, h, w, C + 1)`` over ``colour`` in place."""
    colour.addcmul_(colour, layer[..., channels:], value=-1.0).add_(layer)  # (1 - a) c + l


def render_fast(
    image: torch.Tensor,
    coc: torch.Tensor,
    params: PSFParams | None = None,
    *,
    model: PSFModel = "ours",
    max_layers: int = 500,
    layers: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Left and right views ``(C, H, W)`` of ``image`` ``(C, H, W)`` blurred by the signed CoC
    map ``coc`` ``(H, W)`` in px; see the module docstring and
    :func:`dualpixel.synthesis.render_dp_views`.

    ``layers``: ``(labels (H, W), layer_coc (L,))`` already cut, e.g. a window's region of its
    whole frame's :func:`~dualpixel.synthesis.layers.quantise_layers`; a window from an origin
    on the :data:`MAX_DOWNSAMPLE` grid with :func:`crop_margin` of context on every side renders
    inside that margin as the same region of the whole frame does (training crops rendered on
    the fly). None: the frame's own layers."""
    channels, height, width = image.shape
    image_hwc = image.permute(1, 2, 0)
    opaque = torch.cat((image_hwc, torch.ones_like(image_hwc[..., :1])), dim=-1)  # [I, 1]
    labels, layer_coc = (quantise_layers(coc, max_layers, mode="fast") if layers is None
                         else layers)
    extents = row_extents(labels, layer_coc.numel())
    boxes = bounding_boxes(labels, layer_coc.numel(), extents).tolist()
    strips = _strip_extents(extents, width)
    radii = layer_coc.tolist()
    # (views, H, W, C + 1): premultiplied colour and coverage
    result = torch.zeros(2, height, width, channels + 1, dtype=image.dtype, device=image.device)
    groups = _groups(radii, boxes)
    tables = layer_kernels([(d, [radii[j] for j in group], params, model)
                            for d, group in groups], image.dtype)
    for (d, group), table in zip(groups, tables):
        if d == 1:
            unblurred: list[int] = []  # consecutive layers whose kernels are exactly [[1]]
            for j, kernels in zip(group, table):
                if kernels.shape[-1] == 1 and bool((kernels == 1.0).all()):
                    unblurred.append(j)
                    continue
                _paste_unblurred(result, opaque, labels, unblurred)
                unblurred = []
                _composite_strips(result, opaque, labels, j, strips[0][j], strips[1][j],
                                  kernels)
            _paste_unblurred(result, opaque, labels, unblurred)
        else:
            _composite_reduced(result, image_hwc, labels, group, boxes, radii, d, params, model,
                               table)
    cover = result[..., channels:].clamp_min(torch.finfo(image.dtype).eps)
    views = (result[..., :channels] / cover).permute(0, 3, 1, 2)
    return views[0], views[1]


#: Full-resolution layers are convolved in bands of this many output rows, each only as wide
#: as the layer's pixels that reach it: a layer spread thinly over the frame (a slanted ground
#: plane, the edges of many objects) costs its pixels' area, not its bounding box's. Adjacent
#: bands are convolved together where that costs no more area, so the number of calls stays
#: about the same from 32 rows down to 4, while the area falls (set0's blurred layers on a
#: 1920x1080 frame: 2.7x the frame at 32 rows, 1.4x at 8); rendering sets 0-3 took 0.45-0.75 of
#: the time of 32-row bands, set4 (mostly at reduced resolution) the same.
STRIP_ROWS = 8
#: Layers whose kernel is over this size (filtered in several passes) always go band by band;
#: smaller kernels only when the bands cover at most ``STRIP_GAIN`` of the bounding box.
STRIP_MIN_KERNEL = CV_MAX_KERNEL
STRIP_GAIN = 0.5


def _strip_extents(extents: tuple[torch.Tensor, torch.Tensor], width: int) -> tuple[list, list]:
    """First and last column of every layer in every band of :data:`STRIP_ROWS` rows, from the
    layers' :func:`~dualpixel.synthesis.layers.row_extents`: two per-layer lists of per-band
    lists; first > last where the band holds none of the layer."""
    first, last = extents
    count, height = first.shape
    bands = -(-height // STRIP_ROWS)
    pad = bands * STRIP_ROWS - height
    first = F.pad(first, (0, pad), value=width)
    last = F.pad(last, (0, pad), value=-1)
    return (first.view(count, bands, STRIP_ROWS).amin(dim=2).tolist(),
            last.view(count, bands, STRIP_ROWS).amax(dim=2).tolist())


def _strip_runs(first: list[int], last: list[int], half: int) -> list[tuple[int, int, int, int]]:
    """Runs of consecutive bands to convolve together, ``(band0, band1, col0, col1)`` with
    inclusive columns of the layer's pixels that reach the run's output rows: a band joins the
    run before it when convolving them together costs no more area than apart."""
    reach = -(-half // STRIP_ROWS)
    runs: list[list[int]] = []

    def area(bands: int, col0: int, col1: int) -> int:
        return (bands * STRIP_ROWS + 2 * half) * (col1 - col0 + 1 + 2 * half)

    for k in range(len(first)):
        near = range(max(k - reach, 0), min(k + reach + 1, len(first)))
        col0, col1 = min(first[i] for i in near), max(last[i] for i in near)
        if col0 > col1:
            continue
        if runs and runs[-1][1] == k - 1:
            b0, b1, r0, r1 = runs[-1]
            joined = area(k - b0 + 1, min(r0, col0), max(r1, col1))
            if joined <= area(b1 - b0 + 1, r0, r1) + area(1, col0, col1):
                runs[-1] = [b0, k, min(r0, col0), max(r1, col1)]
                continue
        runs.append([k, k, col0, col1])
    return [tuple(run) for run in runs]


def _groups(radii: list[float], boxes: list[list[int]]) -> list[tuple[int, list[int]]]:
    """The layers far to near in groups of one downsampling factor ``(d, layers)``: runs of
    consecutive layers of the whole layering, then only the layers present (row1 >= 0 in
    ``boxes``), so a window's groups are its frame's, less what it does not hold."""
    order = sorted(range(len(radii)), key=lambda j: -radii[j])  # far to near
    groups: list[tuple[int, list[int]]] = []
    for j in order:
        d = downsample_factor(radii[j])
        if not groups or groups[-1][0] != d:
            groups.append((d, []))
        groups[-1][1].append(j)
    present = [(d, [j for j in group if boxes[j][1] >= 0]) for d, group in groups]
    return [(d, group) for d, group in present if group]


def crop_margin(max_coc: float, model: PSFModel = "ours", kappa: float = 0.14) -> int:
    """Pixels of context a crop needs on every side so that its render equals the same region of
    the whole frame's, for a frame whose largest |CoC| is ``max_coc`` px: the largest kernel's
    reach at its resolution 1/d, plus a cell of pooling and the bicubic support there (4 cells
    of d px), rounded up to d. The crop's origin must lie on the d-px grid (d =
    :func:`downsample_factor` of ``max_coc``; the 16-px grid serves every frame)."""
    d = downsample_factor(max_coc)
    reach = max(kernel_size(max_coc, model, kappa) // 2,
                d * (kernel_size(max_coc / d, model, kappa) // 2 + 4))
    return -(-reach // d) * d


def _composite_strips(result, opaque, labels, j, first, last, kernels) -> None:
    """Layer ``j`` at full resolution, in runs of bands (:func:`_strip_runs`): each run of output
    rows gets exactly the layer's blurred planes (from the input rows around it, as wide as the
    layer's pixels there); runs do not overlap, so compositing is the same as for the whole
    layer. ``opaque``: the image with a plane of ones, ``(H, W, C + 1)``."""
    height, width = opaque.shape[:2]
    channels = opaque.shape[-1] - 1
    half = kernels.shape[-1] // 2
    runs = _strip_runs(first, last, half)
    whole = (runs[0][0], runs[-1][1], min(r[2] for r in runs), max(r[3] for r in runs))
    if kernels.shape[-1] <= STRIP_MIN_KERNEL:
        # one call per band costs more than its area for a cheap kernel: split only when the
        # bands save most of the bounding box
        area = sum((r[1] - r[0] + 1) * (r[3] - r[2] + 1 + 2 * half) for r in runs)
        if area > STRIP_GAIN * (whole[1] - whole[0] + 1) * (whole[3] - whole[2] + 1 + 2 * half):
            runs = [whole]
    for band0, band1, col0, col1 in runs:
        out0, out1 = band0 * STRIP_ROWS, min((band1 + 1) * STRIP_ROWS, height)
        in0, in1 = max(out0 - half, 0), min(out1 + half, height)
        c0, c1 = max(col0 - half, 0), min(col1 + half + 1, width)
        mask = (labels[in0:in1, c0:c1] == j)[..., None]
        planes = torch.where(mask, opaque[in0:in1, c0:c1], 0.0)  # [I m, m]
        blurred = _convolve(planes, kernels)[:, out0 - in0 : out1 - in0]
        _over(result[:, out0:out1, c0:c1], blurred, channels)


def _paste_unblurred(result, opaque, labels, layers: list[int]) -> None:
    """Layers whose kernels are exactly ``[[1]]`` (consecutive in depth, so consecutive labels):
    each is opaque exactly on its own pixels, so compositing them one by one leaves ``opaque``
    (``[I, 1]``, ``(H, W, C + 1)``) there and nothing elsewhere; one indexed copy gives the same
    bytes as :func:`_composite_strips` for each (whose cost is the layers' band area, about 5x
    their pixels for the thin near-focus layers of a slanted surface)."""
    if not layers:
        return
    height, width, planes = opaque.shape
    low, high = min(layers), max(layers)
    where = torch.nonzero(((labels >= low) & (labels <= high)).flatten())[:, 0]
    values = opaque.reshape(-1, planes)[where]
    result.view(2, height * width, planes).index_copy_(1, where, values.expand(2, -1, -1))


def _composite_reduced(result, image_hwc, labels, group, boxes, radii, d, params, model,
                       table) -> None:
    """Layers of one downsampling factor ``d`` (far to near), with their kernels at 1/d
    (``table``): area-averaged to 1/d, blurred and composited there, then upsampled (bicubic)
    and composited over ``result``."""
    height, width, channels = image_hwc.shape
    largest = max(abs(radii[j]) for j in group)
    half = kernel_size(largest, model, (params or PSFParams()).kappa) // 2
    member = [boxes[j] for j in group]
    r0 = max(min(b[0] for b in member) - half, 0) // d * d
    c0 = max(min(b[2] for b in member) - half, 0) // d * d
    r1 = min(max(b[1] for b in member) + half + 1, height)
    c1 = min(max(b[3] for b in member) + half + 1, width)
    lh, lw = -(-(r1 - r0) // d), -(-(c1 - c0) // d)
    # the group's pixels sorted by layer, then per layer the d x d block sums of [I m, m] over
    # its own box only (bincount sums in a fixed order, whatever the number of threads)
    local = torch.full((len(radii),), -1, dtype=torch.long, device=labels.device)
    local[torch.tensor(group, device=labels.device)] = torch.arange(len(group),
                                                                     device=labels.device)
    crop = local[labels[r0:r1, c0:c1]].flatten()
    where = torch.nonzero(crop >= 0)[:, 0]
    members, order = torch.sort(crop[where], stable=True)
    where = where[order]
    offsets = [0, *torch.cumsum(torch.bincount(members, minlength=len(group)), 0).tolist()]
    low_rows, low_cols = (where // (c1 - c0)) // d, (where % (c1 - c0)) // d
    values = image_hwc[r0:r1, c0:c1].reshape(-1, channels)[where]
    layer = torch.zeros(2, lh, lw, channels + 1, dtype=image_hwc.dtype, device=image_hwc.device)
    for k, (j, kernels) in enumerate(zip(group, table)):
        row0, row1, col0, col1 = boxes[j]
        box = ((row0 - r0) // d, (row1 - r0) // d, (col0 - c0) // d, (col1 - c0) // d)
        b0, b1, b2, b3 = grown_box(box, kernels.shape[-1] // 2, lh, lw)
        part = slice(offsets[k], offsets[k + 1])
        cell = (low_rows[part] - b0) * (b3 - b2) + (low_cols[part] - b2)
        cells = (b1 - b0) * (b3 - b2)
        sums = [torch.bincount(cell, weights=values[part, c], minlength=cells)
                for c in range(channels)]
        sums.append(torch.bincount(cell, minlength=cells).to(sums[0].dtype))
        pooled = (torch.stack(sums, dim=-1) / (d * d)).to(image_hwc.dtype)
        pooled = pooled.view(b1 - b0, b3 - b2, channels + 1)
        _over(layer[:, b0:b1, b2:b3], _convolve(pooled, kernels), channels)
    for lo0, lo1, lo2, lo3 in _covered_regions(layer[..., channels:]):
        # bicubic output rows/cols whose 4-tap support touches the covered low-res cells, from
        # a block two cells wider (so the block's border never enters): equal to upsampling all
        y0, y1 = max(lo0 - 2, 0) * d, min(lo1 + 2, lh) * d
        x0, x1 = max(lo2 - 2, 0) * d, min(lo3 + 2, lw) * d
        k0, k2 = max(lo0 - 4, 0), max(lo2 - 4, 0)
        block = _upsample(layer[:, k0:min(lo1 + 4, lh), k2:min(lo3 + 4, lw)], d)
        block = block[:, y0 - k0 * d : y1 - k0 * d, x0 - k2 * d : x1 - k2 * d]
        rows, cols = min(y1, r1 - r0) - y0, min(x1, c1 - c0) - x0
        if rows > 0 and cols > 0:
            _over(result[:, r0 + y0 : r0 + y0 + rows, c0 + x0 : c0 + x0 + cols],
                  block[:, :rows, :cols], channels)
