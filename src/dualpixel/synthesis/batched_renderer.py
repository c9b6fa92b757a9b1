"""The layered renderer for many frames at once, one code path for CPU and GPU tensors.

The default renderer (:mod:`dualpixel.synthesis.fast_renderer`) takes one frame and walks its
layers one by one in small pieces, which suits two CPU cores and leaves a GPU idle. This one
renders a batch of frames (or crops) with the **same layers, compositing and reduced-resolution
rule** (paper Sec. 3, Eq. 7; the fast layering of :func:`~dualpixel.synthesis.layers.
quantise_layers`, layers with ``|r| >= d * R_LOW`` at 1/d resolution, the same trimmed PSFs), but
in whole-frame tensor operations:

1. Each frame's layers, sorted far to near, fall into *runs* of one downsampling factor d (at most
   nine: d falls towards focus and rises again in front of it). Runs of the same d, from every
   frame, are rendered together: layer k of every such run is convolved in one call (a depthwise
   ``conv2d`` for small kernels, FFT for large ones) and composited back to front at 1/d, at full
   resolution only in the :data:`TILE`-px tiles its blur reaches, at reduced ones inside the
   union of the runs' boxes. The PSF kernels are made on the CPU and sent once per layer.
2. Each run's premultiplied colour and coverage are upsampled (bicubic) and the runs composited
   far to near over each frame, then normalised by the coverage (the hidden background rule).

``layers`` hands in layers already cut: a crop given its region of the whole frame's layers
(:func:`~dualpixel.synthesis.layers.quantise_layers` on the whole frame), from an origin on the
16-px grid and with its blur margin (:func:`crop_margin`), renders as that region of the whole
frame's render does, which is what on-the-fly training crops need.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

from dualpixel.errors import ParameterError
from dualpixel.optics.psf import PSFModel, PSFParams, check_psf_model
from dualpixel.synthesis.fast_renderer import _groups, crop_margin, layer_kernels
from dualpixel.synthesis.layers import bounding_boxes, quantise_layers

__all__ = ["DIRECT_MAX_KERNEL", "crop_margin", "render_batch"]

#: Kernels up to this size are convolved directly (a depthwise ``conv2d``), larger ones by FFT,
#: per device type. Measured on 2 CPU cores (8 crops of 320x240, 4 planes): direct 0.03 s at
#: S = 3, 0.11 s at 11, 0.36 s at 25; FFT 0.07-0.11 s whatever S. On a GPU every kernel of the
#: full-resolution layers (|r| < 4 px: S <= 15) and of the reduced ones (S <= 21) goes direct.
DIRECT_MAX_KERNEL = {"cpu": 7, "other": 21}
#: Layers at full resolution (d <= :data:`TILED_MAX_FACTOR`) are convolved and composited in
#: output tiles of this many pixels square, only those their blur reaches; reduced ones in the
#: union of their boxes, a small frame that tiles' halos would cover several times over. The
#: union of the boxes covered 63 times the layers' own pixels on 16 set0 frames of 1920x1080.
#: Measured on 2 CPU cores (set0; 2 frames of 1920x1080 / 4 of 840x560): boxes alone 4.9 /
#: 5.3 s, tiles of 8 px 2.8 / 1.9 s, 16 px 2.3 / 1.5 s, 32 px 2.8 / 2.3 s, 64 px 5.1 s.
TILE = 16
#: The coarsest resolution rendered in tiles. Tiles up to d = 2 against d = 1 alone (2 CPU
#: cores): set2 at 1920x1080 6.1 s against 14.3, but set0 and set4 10-20 % slower and
#: on-the-fly training crops (dslr-840, `bench_synthesis.py --training`) 5 % slower; up to
#: d = 4, set4 1.5x slower.
TILED_MAX_FACTOR = 1


@dataclass
class _Run:
    """Layers of one frame with one downsampling factor, consecutive far to near."""

    frame: int
    d: int
    layers: list[int]
    radii: list[float]  # CoC radius (px, full resolution) per layer
    boxes: list[list[int]]  # (row0, row1, col0, col1) inclusive per layer, full resolution
    # (2, S, S) per layer, at 1/d, on the CPU
    kernels: list[torch.Tensor] = field(default_factory=list)


def _runs(labels: torch.Tensor, layer_coc: torch.Tensor, frame: int) -> list[_Run]:
    """The runs of one frame's layers present in ``labels`` (far to near, grouped as the
    default renderer groups them), their kernels not made yet (:func:`_with_kernels`)."""
    radii = layer_coc.tolist()
    boxes = bounding_boxes(labels, len(radii)).tolist()
    return [_Run(frame, d, group, radii=[radii[j] for j in group],
                 boxes=[boxes[j] for j in group]) for d, group in _groups(radii, boxes)]


def _with_kernels(runs: list[list[_Run]], params: list[PSFParams | None],
                  models: list[PSFModel], dtype: torch.dtype) -> None:
    """Every run's kernels (its frame's PSF shape and model, at 1/d), made in one
    :func:`~dualpixel.synthesis.fast_renderer.layer_kernels` call for all the frames."""
    every = [(run, b) for b, frame in enumerate(runs) for run in frame]
    tables = layer_kernels([(run.d, run.radii, params[b], models[b]) for run, b in every], dtype)
    for (run, _), table in zip(every, tables):
        run.kernels = table


def _convolve(planes: torch.Tensor, kernels: torch.Tensor, *, valid: bool = False
              ) -> torch.Tensor:
    """``(R, P, h, w)`` planes, each with its own ``(R, 2, S, S)`` kernels (true convolution):
    ``(R, 2, P, h, w)`` with zero padding, or with ``valid`` only where the kernel lies wholly
    inside, ``(R, 2, P, h - S + 1, w - S + 1)``."""
    runs, count, height, width = planes.shape
    size = kernels.shape[-1]
    crop = size - 1 if valid else size // 2  # where the output starts in the full convolution
    out_size = (height - size + 1, width - size + 1) if valid else (height, width)
    cpu = planes.device.type == "cpu"
    if size <= DIRECT_MAX_KERNEL["cpu" if cpu else "other"]:
        weight = torch.flip(kernels, dims=(-2, -1))  # conv2d correlates
        weight = weight[:, None].expand(runs, count, 2, size, size).reshape(-1, 1, size, size)
        source = planes.reshape(1, runs * count, height, width)
        if cpu:  # oneDNN's depthwise kernels want channels last: 2-3x faster
            source = source.contiguous(memory_format=torch.channels_last)
        out = F.conv2d(source, weight.contiguous(), padding=0 if valid else size // 2,
                       groups=runs * count)
        return out.reshape(runs, count, 2, *out_size).transpose(1, 2)
    from scipy.fft import next_fast_len

    if valid:  # overlap-save: a circular convolution of period >= h, w leaves this part exact
        full = (next_fast_len(height, real=True), next_fast_len(width, real=True))
    else:
        full = (next_fast_len(height + size - 1, real=True),
                next_fast_len(width + size - 1, real=True))
    spectrum = (torch.fft.rfft2(planes, s=full)[:, None]
                * torch.fft.rfft2(kernels, s=full)[:, :, None])
    return torch.fft.irfft2(spectrum, s=full)[..., crop : crop + out_size[0],
                                              crop : crop + out_size[1]]


def _padded(kernels: list[torch.Tensor], size: int) -> torch.Tensor:
    """``(2, s, s)`` kernels (on the CPU), each zero-padded about its centre, stacked as
    ``(K, 2, size, size)`` on the CPU (to go to the device in one copy)."""
    out = torch.zeros(len(kernels), 2, size, size, dtype=kernels[0].dtype)
    for k, kernel in zip(out, kernels):
        pad = (size - kernel.shape[-1]) // 2
        k[:, pad : size - pad, pad : size - pad] = kernel
    return out


def _tile_presence(labels: torch.Tensor, count: int) -> torch.Tensor:
    """Which :data:`TILE`-px tiles of a frame's ``(H, W)`` labels hold each of its ``count``
    layers: ``(count, ceil(H / TILE), ceil(W / TILE))`` bool."""
    height, width = labels.shape
    tiles = (-(-height // TILE), -(-width // TILE))
    rows = torch.arange(height, device=labels.device) // TILE
    cols = torch.arange(width, device=labels.device) // TILE
    cell = (rows[:, None] * tiles[1] + cols[None, :]).flatten()
    key = labels.flatten() * (tiles[0] * tiles[1]) + cell
    counts = torch.bincount(key, minlength=count * tiles[0] * tiles[1])
    return (counts > 0).view(count, *tiles)


def _tiled(values: torch.Tensor, step: int, size: int) -> torch.Tensor:
    """Overlapping square windows of ``(B, ..., H, W)`` values, ``size`` px from every
    ``step``-th pixel: a ``(B, H // step, W // step, ..., size, size)`` view (no copy), whole
    windows only."""
    rows, cols = (values.shape[-2] - size) // step + 1, (values.shape[-1] - size) // step + 1
    stride = values.stride()
    middle = values.shape[1:-2]
    return values.as_strided(
        (values.shape[0], rows, cols, *middle, size, size),
        (stride[0], step * stride[-2], step * stride[-1], *stride[1:-2], stride[-2], stride[-1]))


def _render_runs_in_tiles(runs: list[_Run], opaque: torch.Tensor, labels: torch.Tensor,
                          presence: list[torch.Tensor], d: int) -> list[torch.Tensor]:
    """Every run of factor ``d`` (all frames together): ``(2, C + 1, H/d, W/d)`` premultiplied
    colour and coverage per run, composited back to front at 1/d. Layer k of every run is
    convolved in one call, on the :data:`TILE`-px output tiles (at 1/d) its blur reaches alone,
    each from its input tile and halo. ``presence``: :func:`_tile_presence` per frame (tiles of
    TILE px at full resolution), on the CPU: the tiles are chosen there, without waiting for the
    device."""
    planes_count, height, width = opaque.shape[1:]
    device = opaque.device
    low = (-(-height // d), -(-width // d))
    tiles = (-(-low[0] // TILE), -(-low[1] // TILE))
    halo = max(k.shape[-1] for run in runs for k in run.kernels) // 2  # at 1/d
    # the frame on the tiles' grid, with a halo of zeros (no layer) on every side, full
    # resolution; every output tile's input window is a view of it
    pad = (halo * d, tiles[1] * TILE * d - width + halo * d,
           halo * d, tiles[0] * TILE * d - height + halo * d)
    window = (TILE + 2 * halo) * d
    source = _tiled(F.pad(opaque, pad), TILE * d, window)  # (B, ty, tx, C + 1, w, w)
    layer_map = _tiled(F.pad(labels, pad, value=-1), TILE * d, window)  # (B, ty, tx, w, w)
    # premultiplied colour and coverage per run, tile by tile
    acc = opaque.new_zeros(len(runs), *tiles, 2, planes_count, TILE, TILE)
    for position in range(max(len(run.layers) for run in runs)):
        active = [k for k, run in enumerate(runs) if position < len(run.layers)]
        kernels = [runs[k].kernels[position] for k in active]
        size = max(k.shape[-1] for k in kernels)
        half = size // 2
        chosen = _reached_tiles([runs[k] for k in active], active, position, presence, d, half)
        if chosen.shape[1] == 0:
            continue
        # every tile's indices to the device in one copy
        which, run, frame, tile_row, tile_col, layer = chosen.to(device, non_blocking=True)
        inner = slice((halo - half) * d, (halo + half + TILE) * d)  # this layer's halo
        planes = _layer_planes(source[frame, tile_row, tile_col][..., inner, inner],
                               layer_map[frame, tile_row, tile_col][:, inner, inner], layer, d)
        blurred = _convolve(planes, _padded(kernels, size).to(device)[which],
                             valid=True)
        acc[run, tile_row, tile_col] = _over(blurred, acc[run, tile_row, tile_col])
    image = acc.permute(0, 3, 4, 1, 5, 2, 6).reshape(len(runs), 2, planes_count,
                                                     tiles[0] * TILE, tiles[1] * TILE)
    return list(image[..., : low[0], : low[1]])


def _render_runs_in_boxes(runs: list[_Run], opaque: torch.Tensor, labels: torch.Tensor,
                          d: int) -> list[torch.Tensor]:
    """Every run of factor ``d`` (all frames together): ``(2, C + 1, H/d, W/d)`` premultiplied
    colour and coverage per run, composited back to front at 1/d. Layer k of every run is
    convolved in one call, inside the union of their boxes grown by the kernels' reach."""
    planes_count, height, width = opaque.shape[1:]
    low = (-(-height // d), -(-width // d))
    pad = (0, low[1] * d - width, 0, low[0] * d - height)
    source = F.pad(opaque, pad) if d > 1 else opaque  # the d x d grid from the frame's origin
    layer_map = F.pad(labels, pad, value=-1) if d > 1 else labels
    acc = opaque.new_zeros(len(runs), 2, planes_count, *low)
    frames = torch.tensor([run.frame for run in runs], device=opaque.device)
    for position in range(max(len(run.layers) for run in runs)):
        active = [k for k, run in enumerate(runs) if position < len(run.layers)]
        index = torch.tensor(active, device=opaque.device)
        layer = torch.tensor([runs[k].layers[position] for k in active], device=opaque.device)
        kernels = [runs[k].kernels[position] for k in active]
        size = max(k.shape[-1] for k in kernels)
        boxes = [runs[k].boxes[position] for k in active]  # inclusive, full resolution
        half = size // 2
        r0, c0 = (max(min(b[i] for b in boxes) // d - half, 0) for i in (0, 2))
        r1 = min(max(b[1] for b in boxes) // d + 1 + half, low[0])
        c1 = min(max(b[3] for b in boxes) // d + 1 + half, low[1])
        rows, cols = slice(r0 * d, r1 * d), slice(c0 * d, c1 * d)
        chosen = frames[index]
        planes = _layer_planes(source[chosen, :, rows, cols], layer_map[chosen, rows, cols],
                               layer, d)
        blurred = _convolve(planes, _padded(kernels, size).to(opaque.device))  # (R, 2, C + 1, h, w)
        acc[index, :, :, r0:r1, c0:c1] = _over(blurred, acc[index, :, :, r0:r1, c0:c1])
    return list(acc)


def _layer_planes(source: torch.Tensor, labels: torch.Tensor, layer: torch.Tensor,
                  d: int) -> torch.Tensor:
    """Each window's ``[I m, m]`` of its own layer (paper Eq. 7's layer term before blur):
    ``source`` ``(N, C + 1, h, w)`` with the coverage last, ``labels`` ``(N, h, w)``, ``layer``
    ``(N,)``; averaged over d x d blocks at 1/d."""
    planes = torch.where((labels == layer[:, None, None])[:, None], source, 0.0)
    return F.avg_pool2d(planes, d) if d > 1 else planes


def _over(front: torch.Tensor, back: torch.Tensor) -> torch.Tensor:
    """Premultiplied ``front`` composited over ``back`` (``(..., C + 1, h, w)``, the coverage
    last: a nearer layer hides what lies behind it)."""
    return front + (1.0 - front[..., -1:, :, :]) * back


def _reached_tiles(runs: list[_Run], active: list[int], position: int,
                   presence: list[torch.Tensor], d: int, half: int) -> torch.Tensor:
    """The output tiles (of :data:`TILE` px at 1/d) that layer ``position`` of each of ``runs``
    (numbered ``active`` in the call) reaches: those holding it (its frame's ``presence``, on
    the CPU) grown by ``half`` px. ``(6, N)`` on the CPU, per tile:
    its run among ``runs``, its run's number, frame, tile row, tile column and layer."""
    reached = torch.stack([_coarse(presence[run.frame][run.layers[position]], d)
                           for run in runs])
    grow = -(-half // TILE)
    if grow:
        reached = F.max_pool2d(reached[:, None].float(), 2 * grow + 1, stride=1,
                               padding=grow)[:, 0] > 0
    which, row, col = torch.nonzero(reached, as_tuple=True)
    frame = torch.tensor([run.frame for run in runs])[which]
    layer = torch.tensor([run.layers[position] for run in runs])[which]
    return torch.stack((which, torch.tensor(active)[which], frame, row, col, layer))


def _on_cpu(tensors: list[torch.Tensor]) -> list[torch.Tensor]:
    """``tensors`` copied to the CPU in one transfer (one wait for the device)."""
    flat = torch.cat([t.flatten() for t in tensors]).cpu()
    return [part.view(t.shape) for part, t in zip(flat.split([t.numel() for t in tensors]),
                                                    tensors)]


def _coarse(held: torch.Tensor, d: int) -> torch.Tensor:
    """A layer's full-resolution tile presence ``(ceil(H / TILE), ceil(W / TILE))`` as tiles of
    ``TILE * d`` px: which of the tiles of TILE px at 1/d hold it (as many:
    ``ceil(ceil(H / TILE) / d) = ceil(ceil(H / d) / TILE)``)."""
    if d == 1:
        return held
    return F.max_pool2d(held[None, None].float(), d, ceil_mode=True)[0, 0] > 0


def _upsampled(layer: torch.Tensor, d: int, height: int, width: int) -> torch.Tensor:
    """``(2, P, h, w)`` at 1/d -> ``(2, P, height, width)``, bicubic, pixel centres aligned."""
    if d == 1:
        return layer
    up = F.interpolate(layer, scale_factor=d, mode="bicubic", align_corners=False)
    return up[..., :height, :width]


def render_batch(
    images: torch.Tensor,
    coc: torch.Tensor,
    params: PSFParams | Sequence[PSFParams | None] | None = None,
    *,
    model: PSFModel | Sequence[PSFModel] = "ours",
    max_layers: int = 500,
    layers: Sequence[tuple[torch.Tensor, torch.Tensor] | None] | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Left and right DP views of a batch of all-in-focus frames (paper Eq. 7, layered).

    Args:
        images: ``(B, C, H, W)`` linear values in [0, 1], on any device (float32 or float64).
        coc: ``(B, H, W)`` signed CoC radius in pixels.
        params: the PSF shape, one for all frames or one per frame (None: the paper's).
        model: the PSF model, one for all or one per frame.
        max_layers: at most this many exact layers per frame (the paper: 500).
        layers: per frame ``(labels (H, W) long, layer_coc (L,))`` already cut (e.g. a crop's
            region of its whole frame's :func:`~dualpixel.synthesis.layers.quantise_layers`),
            or None to cut the frame's own (``mode="fast"``).

    Returns:
        ``(left, right)``, each ``(B, C, H, W)``, at the combined image's brightness, as
        :func:`~dualpixel.synthesis.render_dp_views` returns them (>= 45 dB from ``exact``).
    """
    if images.ndim != 4 or coc.shape != (images.shape[0], *images.shape[-2:]):
        raise ParameterError(f"images must be (B, C, H, W) and coc (B, H, W) of the same size; "
                             f"got images {tuple(images.shape)} and coc {tuple(coc.shape)}")
    if not images.dtype.is_floating_point:
        raise ParameterError(f"images must be floating point, got {images.dtype}")
    batch, channels, height, width = images.shape
    per_frame_params = (list(params) if isinstance(params, Sequence) else [params] * batch)
    models = [model] * batch if isinstance(model, str) else list(model)
    given = [None] * batch if layers is None else list(layers)
    if not len(per_frame_params) == len(models) == len(given) == batch:
        raise ParameterError(f"params, model and layers need one entry per frame ({batch})")
    for name in models:
        check_psf_model(name)
    coc = coc.to(images.dtype)
    opaque = torch.cat((images, torch.ones_like(images[:, :1])), dim=1)  # [I, 1]
    labels = torch.empty(coc.shape, dtype=torch.long, device=coc.device)
    runs: list[list[_Run]] = []
    counts: list[int] = []  # layers per frame
    for b in range(batch):
        if given[b] is None:
            frame_labels, layer_coc = quantise_layers(coc[b], max_layers, mode="fast")
        else:
            frame_labels, layer_coc = given[b]
            if frame_labels.shape != (height, width):
                raise ParameterError(f"frame {b}: layer labels {tuple(frame_labels.shape)} and "
                                     f"image {(height, width)} differ in size")
        labels[b] = frame_labels.to(coc.device)
        counts.append(layer_coc.numel())
        runs.append(_runs(labels[b], layer_coc.to(images.dtype), b))
    _with_kernels(runs, per_frame_params, models, images.dtype)
    results: dict[tuple[int, int], torch.Tensor] = {}
    presence: list[torch.Tensor] = []  # per frame, made once a tiled factor needs it
    for d in sorted({run.d for frame in runs for run in frame}):
        same = [(b, k) for b, frame in enumerate(runs) for k, run in enumerate(frame)
                if run.d == d]
        chosen = [runs[b][k] for b, k in same]
        if d <= TILED_MAX_FACTOR:
            presence = presence or _on_cpu([_tile_presence(labels[b], count)
                                            for b, count in enumerate(counts)])
            rendered = _render_runs_in_tiles(chosen, opaque, labels, presence, d)
        else:
            rendered = _render_runs_in_boxes(chosen, opaque, labels, d)
        results.update(zip(same, rendered))
    left, right = [], []
    for b, frame in enumerate(runs):
        total = opaque.new_zeros(2, channels + 1, height, width)
        for k, run in enumerate(frame):  # far to near
            layer = _upsampled(results.pop((b, k)), run.d, height, width)
            total = _over(layer, total)
        cover = total[:, channels:].clamp_min(torch.finfo(images.dtype).eps)
        views = total[:, :channels] / cover
        left.append(views[0])
        right.append(views[1])
    return torch.stack(left), torch.stack(right)

