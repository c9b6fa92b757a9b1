"""Evaluating deblurring as in the paper's Table 1: per-image metrics, category summaries, reports.

Rows are methods: ``input`` (the combined blurred image), the model being evaluated (timed per
image), and any other method's outputs (a folder of images named like the examples, or extra images
in scene folders such as ``dpdnet.png``). Columns are PSNR / SSIM / MAE per category (Indoor,
Outdoor, Combined when a category list is given), NIQE and seconds per image; with ``align``, also
PSNR and SSIM after registering each output to its target (:mod:`dualpixel.evaluation.alignment`).
"""

from __future__ import annotations

import csv
import io
import json
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualpixel.data.layout import DPSequence
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.evaluation.alignment import AlignmentError, align_to_target
from dualpixel.evaluation.blur_breakdown import BlurBreakdown, read_defocus
from dualpixel.evaluation.metrics import mae, psnr, ssim
from dualpixel.evaluation.niqe import NIQEModel, niqe
from dualpixel.evaluation.temporal import FlickerMeter
from dualpixel.io.atomic import atomic_path
from dualpixel.io.documents import read_text_file
from dualpixel.io.images import IMAGE_SUFFIXES, max_level, read_rgb, read_views
from dualpixel.optics.tone import combined_image
from dualpixel.progress import progress_bar

if TYPE_CHECKING:
    from dualpixel.inference.encoding import ViewEncoding

__all__ = [
    "EvalExample",
    "ImageResult",
    "by_position",
    "evaluate",
    "evaluate_folders",
    "examples_from_sequences",
    "markdown_table",
    "position_markdown",
    "read_categories",
    "summarise",
    "write_reports",
]


@dataclass
class EvalExample:
    """One image to score: its name, sequence, views, target, other methods' outputs, for
    synthetic data its defocus map (see :mod:`dualpixel.evaluation.blur_breakdown`) and, in a
    sequence of several frames, its ``position`` (0 for the first)."""

    name: str
    sequence: str
    left: Path
    right: Path
    target: Path
    combined: Path | None = None
    others: dict[str, Path] = field(default_factory=dict)
    defocus: Path | None = None
    position: int | None = None


@dataclass
class ImageResult:
    name: str
    method: str
    category: str
    psnr: float
    ssim: float
    mae: float
    niqe: float | None
    seconds: float | None
    aligned_psnr: float | None = None
    aligned_ssim: float | None = None
    position: int | None = None  # the frame's place in its sequence (0 first); None: one frame


def examples_from_sequences(
    sequences: list[DPSequence], others: dict[str, dict[str, Path]] | None = None,
    compare: dict[str, Path] | None = None,
) -> list[EvalExample]:
    """Flatten sequences into examples (``seq/frame`` names for multi-frame sequences) and attach
    other methods' outputs: per-scene extras and ``compare`` folders (files named like examples)."""
    examples = []
    for sequence in sequences:
        for position, frame in enumerate(sequence.frames):
            if frame.target is None:
                raise InputFileError(frame.left, "no target to evaluate against")
            multi = len(sequence.frames) > 1
            name = f"{sequence.name}/{frame.left.stem}" if multi else sequence.name
            extra = dict((others or {}).get(sequence.name, {}))
            for method, folder in (compare or {}).items():
                matches = [folder / f"{name}{s}" for s in IMAGE_SUFFIXES]
                found = [m for m in matches if m.is_file()]
                if not found:
                    raise InputFileError(folder, f"no output of {method!r} for {name}")
                extra[method] = found[0]
            examples.append(EvalExample(name, sequence.name, frame.left, frame.right,
                                        frame.target, frame.combined, extra, frame.defocus,
                                        position if multi else None))
    return examples


def read_categories(path: str | Path) -> dict[str, str]:
    """``name,category`` lines (CSV, ``#`` comments allowed), e.g. the DPDD indoor/outdoor list."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "category list not found")
    categories = {}
    for number, line in enumerate(read_text_file(path, "category list").splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p.strip() for p in line.replace("\t", ",").split(",")]
        if len(parts) != 2 or not all(parts):
            raise InputFileError(path, f"line {number}: expected 'name,category', got {line!r}")
        categories[Path(parts[0]).stem if "/" not in parts[0] else parts[0]] = parts[1].lower()
    return categories


def _score(method: str, name: str, category: str, output: np.ndarray, target: np.ndarray,
           niqe_model: NIQEModel | None, seconds: float | None, source: Path,
           align: str | None = None) -> ImageResult:
    if output.shape != target.shape:
        raise InputFileError(source, f"size {output.shape[1]}x{output.shape[0]} differs from the "
                                     f"target ({target.shape[1]}x{target.shape[0]})")
    try:  # a metric that cannot score images this small names the file
        score = niqe(output, niqe_model) if niqe_model is not None else None
        result = ImageResult(name, method, category, psnr(output, target), ssim(output, target),
                             mae(output, target), score, seconds)
    except ParameterError as error:
        raise InputFileError(source, str(error)) from None
    if align is not None:
        try:
            pair = align_to_target(output, target, align)
        except AlignmentError as error:
            warnings.warn(f"{source}: {error}; its aligned scores are left out", stacklevel=2)
        else:
            result.aligned_psnr = psnr(pair.prediction, pair.target)
            result.aligned_ssim = ssim(pair.prediction, pair.target)
    return result


def _deblur_views(deblur: Callable[[np.ndarray, np.ndarray], np.ndarray], left: np.ndarray,
                  right: np.ndarray, bits: int, encoding: ViewEncoding | None) -> np.ndarray:
    """``deblur`` of views ``(H, W, C)`` as read from ``bits``-bit files, fed as ``dualpixel
    deblur`` feeds them (:func:`~dualpixel.inference.encoding.deblur_encoded`: in their
    encoding, grey files as one channel); the output ``(H, W, 3)``, grey copied, for scoring."""
    from dualpixel.inference.encoding import deblur_encoded

    return _as_rgb(deblur_encoded(deblur, left, right, encoding, scale=max_level(bits)))


def _as_rgb(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)``: a grey image's one channel copied to R, G and B."""
    return np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image


def evaluate(
    examples: list[EvalExample],
    *,
    deblur: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    reset: Callable[[], None] | None = None,
    method: str = "model",
    niqe_model: NIQEModel | None = None,
    categories: dict[str, str] | None = None,
    save_outputs: Callable[[EvalExample, np.ndarray], None] | None = None,
    progress: bool = True,
    breakdown: BlurBreakdown | None = None,
    align: str | None = None,
    encoding: ViewEncoding | None = None,
    flicker: FlickerMeter | None = None,
    afresh: bool = False,
) -> list[ImageResult]:
    """Score the input, the model (``deblur(left, right)``; ``reset()`` between sequences) and
    every other method of each example; pool errors by blur size into ``breakdown`` where the
    examples have defocus maps; ``align`` ("translation" or "affine") adds scores after
    registering each output to its target. ``encoding``: how the views and targets store light
    (linear raw ones, levels in the files' units, go to the model as ``deblur`` takes them and
    come back raw; every score is taken in the files' own values). ``flicker`` pools the
    frame-to-frame change of each method in static regions of sequences
    (:mod:`dualpixel.evaluation.temporal`). ``afresh``: ``reset()`` before every frame, so a
    temporal model runs each frame of a sequence on its own, as a frame model does."""
    results, current = [], None
    for example in progress_bar(examples, desc="evaluating", unit="image", enabled=progress):
        first = len(results)
        known = categories or {}
        category = known.get(example.sequence, known.get(example.name, ""))
        if categories and not category:
            raise InputFileError(example.left, f"{example.name} is not in the category list")
        target = read_rgb(example.target)
        left, right, (bits, _) = read_views(example.left, example.right)
        combined = (read_rgb(example.combined) if example.combined else _as_rgb(
            combined_image(left, right, encoding=encoding.encoding if encoding else "srgb")))
        results.append(_score("input", example.name, category, combined, target, niqe_model,
                              None, example.combined or example.left, align))
        images = {"input": combined}
        if deblur is not None:
            if (afresh or example.sequence != current) and reset is not None:
                reset()
            current = example.sequence
            started = time.perf_counter()
            output = _deblur_views(deblur, left, right, bits, encoding)
            seconds = time.perf_counter() - started
            results.append(_score(method, example.name, category, output, target, niqe_model,
                                  seconds, example.left, align))
            images[method] = output
            if save_outputs is not None:
                save_outputs(example, output)
        for other, path in sorted(example.others.items()):
            images[other] = read_rgb(path)
            results.append(_score(other, example.name, category, images[other], target,
                                  niqe_model, None, path, align))
        if breakdown is not None and example.defocus is not None:
            breakdown.add(read_defocus(example.defocus, target.shape[:2]), images, target)
        if flicker is not None:
            flicker.add(example.sequence, target, images)
        for result in results[first:]:
            result.position = example.position
    return results


def summarise(results: list[ImageResult]) -> dict[str, dict[str, dict[str, float]]]:
    """Means per method and category (``combined`` = all images): psnr, ssim, mae; for
    ``combined`` also niqe, seconds and the aligned psnr / ssim (None where not measured)."""
    summary: dict[str, dict[str, dict[str, float]]] = {}
    methods = list(dict.fromkeys(r.method for r in results))
    categories = sorted({r.category for r in results if r.category})
    for method in methods:
        rows = [r for r in results if r.method == method]
        summary[method] = {}
        for category in [*categories, "combined"]:
            chosen = [r for r in rows if category == "combined" or r.category == category]
            entry = {key: float(np.mean([getattr(r, key) for r in chosen]))
                     for key in ("psnr", "ssim", "mae")}
            entry["count"] = len(chosen)
            if category == "combined":
                for key in ("niqe", "seconds", "aligned_psnr", "aligned_ssim"):
                    values = [getattr(r, key) for r in chosen if getattr(r, key) is not None]
                    entry[key] = float(np.mean(values)) if values else None
            summary[method][category] = entry
    return summary


def by_position(results: list[ImageResult]) -> dict[str, list[dict[str, float]]]:
    """Means per method and frame position in the sequence (the paper's question for RDPD: does
    the gain grow along the sequence?): per method, one entry per position (0 first) with
    psnr, ssim, mae and count; empty when no result lies in a sequence of several frames."""
    table: dict[str, list[dict[str, float]]] = {}
    placed = [r for r in results if r.position is not None]
    for method in dict.fromkeys(r.method for r in placed):
        rows = [r for r in placed if r.method == method]
        table[method] = []
        for position in sorted({r.position for r in rows}):
            chosen = [r for r in rows if r.position == position]
            entry = {key: float(np.mean([getattr(r, key) for r in chosen]))
                     for key in ("psnr", "ssim", "mae")}
            table[method].append({"position": position, **entry, "count": len(chosen)})
    return table


def position_markdown(table: dict[str, list[dict[str, float]]]) -> str:
    """:func:`by_position`'s PSNR (dB) as a Markdown table: methods by frame position."""
    positions = [entry["position"] for entry in next(iter(table.values()))]
    lines = ["| Method | " + " | ".join(f"frame {p + 1}" for p in positions) + " |",
             "|---|" + "---|" * len(positions)]
    for method, entries in table.items():
        cells = {entry["position"]: f"{entry['psnr']:.2f}" for entry in entries}
        lines.append(f"| {method} | " + " | ".join(cells.get(p, "–") for p in positions) + " |")
    return "\n".join(lines) + "\n"


def markdown_table(summary: dict[str, dict[str, dict[str, float]]]) -> str:
    """The summary as a Markdown table in the layout of the paper's Table 1."""
    categories = list(next(iter(summary.values())).keys())
    aligned = any(m["combined"].get("aligned_psnr") is not None for m in summary.values())
    head = "| Method | " + " | ".join(
        f"{c.capitalize()} PSNR ↑ | SSIM ↑ | MAE ↓" for c in categories
    ) + (" | Aligned PSNR ↑ | Aligned SSIM ↑" if aligned else "") + " | NIQE ↓ | Time (s) ↓ |"
    lines = [head, "|" + "---|" * (1 + 3 * len(categories) + 2 + 2 * aligned)]
    for method, per_category in summary.items():
        cells = []
        for category in categories:
            e = per_category[category]
            cells += [f"{e['psnr']:.2f}", f"{e['ssim']:.3f}", f"{e['mae']:.3f}"]
        combined = per_category["combined"]
        if aligned:
            cells += ["–" if combined.get(key) is None else f"{combined[key]:{form}}"
                      for key, form in (("aligned_psnr", ".2f"), ("aligned_ssim", ".3f"))]
        niqe_cell = "–" if combined.get("niqe") is None else f"{combined['niqe']:.2f}"
        time_cell = "–" if combined.get("seconds") is None else f"{combined['seconds']:.3f}"
        lines.append(f"| {method} | " + " | ".join(cells) + f" | {niqe_cell} | {time_cell} |")
    return "\n".join(lines) + "\n"


def write_reports(results: list[ImageResult], output: str | Path, *, meta: dict | None = None,
                  breakdown: BlurBreakdown | None = None,
                  flicker: FlickerMeter | None = None) -> dict:
    """Write ``per_image.csv``, ``summary.json`` and ``summary.md`` atomically; return the
    summary. A filled ``breakdown`` adds PSNR by blur size to both summaries, a ``flicker``
    meter that saw consecutive frames the change in static regions, sequences of several
    frames the scores by frame position (:func:`by_position`)."""
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(ImageResult.__dataclass_fields__))
    writer.writeheader()
    for result in results:
        writer.writerow(asdict(result))
    summary = summarise(results)
    extra, table = dict(meta or {}), markdown_table(summary)
    if breakdown is not None and breakdown.images:
        extra["by_blur"] = breakdown.table()
        table += "\nBy true |CoC| radius (errors pooled over all images):\n\n" + \
            breakdown.markdown()
    positions = by_position(results)
    if positions:
        extra["by_position"] = positions
        table += "\nPSNR (dB) by frame position in the sequence:\n\n" + \
            position_markdown(positions)
    if flicker is not None and flicker.table():
        extra["flicker"] = flicker.table()
        table += ("\nFrame-to-frame change in static regions (flicker; "
                  f"{flicker.pairs} pairs of consecutive frames):\n\n" + flicker.markdown())
    files = {
        "per_image.csv": buffer.getvalue(),
        "summary.json": json.dumps({"summary": summary, **extra}, indent=2),
        "summary.md": table,
    }
    for name, text in files.items():
        with atomic_path(output / name) as tmp:
            tmp.write_text(text)
    return summary


def evaluate_folders(
    predictions: Path, targets: Path, *, niqe_model: NIQEModel | None = None,
    categories: dict[str, str] | None = None, method: str = "prediction",
    align: str | None = None,
) -> list[ImageResult]:
    """Score every target against the prediction of the same name (any image suffix); ``align``
    as in :func:`evaluate`."""
    target_files = sorted(p for p in Path(targets).rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
    if not target_files:
        raise InputFileError(targets, "no images found")
    results = []
    for target_path in progress_bar(target_files, desc="evaluating", unit="image"):
        name = str(target_path.relative_to(targets).with_suffix(""))
        found = [Path(predictions) / f"{name}{s}" for s in IMAGE_SUFFIXES]
        found = [p for p in found if p.is_file()]
        if not found:
            raise InputFileError(Path(predictions) / name, "prediction missing for this target")
        category = (categories or {}).get(name, "")
        results.append(_score(method, name, category, read_rgb(found[0]), read_rgb(target_path),
                              niqe_model, None, found[0], align))
    return results
