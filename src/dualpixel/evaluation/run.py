"""A whole evaluation as ``dualpixel eval`` runs it: find the examples, deblur them, score them,
draw the comparison figures and write the reports (Table 1 layout)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dualpixel.data.layout import discover_dp_dataset, discover_scene_folders
from dualpixel.errors import ParameterError
from dualpixel.evaluation.alignment import check_align_mode
from dualpixel.evaluation.blur_breakdown import BlurBreakdown
from dualpixel.evaluation.evaluate import (
    evaluate,
    evaluate_folders,
    examples_from_sequences,
    read_categories,
    write_reports,
)
from dualpixel.evaluation.niqe import resolve_niqe_model
from dualpixel.evaluation.temporal import FlickerMeter
from dualpixel.io.atomic import check_writable
from dualpixel.io.dpdd import role_folder
from dualpixel.io.images import read_rgb, write_png
from dualpixel.io.paths import check_plain_name

if TYPE_CHECKING:
    from dualpixel.inference.encoding import ViewEncoding

__all__ = ["EvaluationRequest", "draw_comparisons", "run_evaluation"]


@dataclass
class EvaluationRequest:
    """What to evaluate: ``dataset`` (DPDD layout or scene folders) with a model, or the
    predictions in ``pred`` against ``target``."""

    output: Path
    dataset: Path | None = None
    split: str = "test"
    pred: Path | None = None
    target: Path | None = None
    compare: dict[str, Path] | None = None
    categories: Path | None = None
    niqe_model: str | None = None  # builtin, standard or a file; see resolve_niqe_model
    niqe: bool = True
    figures: int = 3
    save_outputs: bool = False
    afresh: bool = False  # every frame of a sequence on its own (a temporal model's state reset)
    align: str | None = None  # "translation" or "affine": also score registered outputs
    # how the views and targets store light (linear raw views: dualpixel.inference.encoding)
    encoding: ViewEncoding | None = None


def run_evaluation(request: EvaluationRequest, deblurrer=None, method: str = "model",
                   meta: dict | None = None) -> Path:
    """Evaluate and write ``summary.json``/``.md``, ``per_image.csv`` and figures into
    ``request.output`` (checked writable before any work), with PSNR by blur size
    (``by_blur.png``) where the dataset has defocus maps; returns the summary's path.
    ``deblurrer``: a :class:`~dualpixel.inference.Deblurrer`, or None to score only the input
    and the other methods."""
    output = Path(request.output)
    if output.exists() and not output.is_dir():
        raise ParameterError(f"--output {output} is a file; give a folder")
    check_writable(output / "summary.json")
    niqe = resolve_niqe_model(request.niqe_model) if request.niqe else None
    cats = read_categories(request.categories) if request.categories else None
    meta = dict(meta or {})
    meta["niqe_model"] = None if niqe is None else \
        f"{request.niqe_model or 'builtin'} ({niqe.source})"
    if request.align is not None:
        meta["align"] = check_align_mode(request.align)
    if request.encoding is not None and request.encoding.linear:
        meta["encoding"] = {"encoding": "linear", "black_level": request.encoding.black_level,
                            "white_level": request.encoding.white_level}
    for name in request.compare or {}:  # rows of the reports, named like no other
        check_plain_name(name, "--compare name")
        if name in ("input", method):
            raise ParameterError(f"--compare name {name!r} is the name of the "
                                 f"{'input' if name == 'input' else 'model'}'s row; choose "
                                 "another")
    breakdown: BlurBreakdown | None = None
    flicker: FlickerMeter | None = None
    if request.pred is not None or request.target is not None:
        if request.pred is None or request.target is None or request.dataset is not None:
            raise ParameterError("give --pred and --target together, without --dataset")
        results = evaluate_folders(request.pred, request.target, niqe_model=niqe, categories=cats,
                                   align=request.align)
    else:
        if request.dataset is None:
            raise ParameterError("give --dataset, or --pred and --target")
        dataset = Path(request.dataset)
        if role_folder(dataset, request.split, "left").is_dir():
            sequences, others = discover_dp_dataset(dataset, request.split), {}
        else:
            sequences, others = discover_scene_folders(dataset)
        meta["view_findings"] = _view_findings(
            sequences, request.encoding, synthesized=(dataset / "dataset.json").is_file())
        examples = examples_from_sequences(sequences, others, request.compare or {})
        if any(example.defocus is not None for example in examples):
            breakdown = BlurBreakdown()
        if any(len(sequence.frames) > 1 for sequence in sequences):
            flicker = FlickerMeter()
        drawn: dict[str, object] = {}

        def keep(example, image):
            if request.save_outputs:
                write_png(output / "outputs" / f"{example.name}.png", image, bit_depth=8)
            if len(drawn) < request.figures:
                drawn[example.name] = image

        results = evaluate(examples, deblur=deblurrer,
                           reset=deblurrer.reset if deblurrer else None, method=method,
                           niqe_model=niqe, categories=cats,
                           save_outputs=keep if deblurrer else None, breakdown=breakdown,
                           align=request.align, encoding=request.encoding, flicker=flicker,
                           afresh=request.afresh)
        draw_comparisons(examples[: request.figures], drawn, results, method, output)
    write_reports(results, output, meta=meta, breakdown=breakdown, flicker=flicker)
    if breakdown is not None and breakdown.images:
        from dualpixel.evaluation.blur_breakdown_figure import render_blur_breakdown

        render_blur_breakdown(breakdown, output / "by_blur.png")
    return output / "summary.md"


def _view_findings(sequences, encoding: ViewEncoding | None = None, *,
                   synthesized: bool = False) -> list[dict[str, str]]:
    """The checks ``deblur`` runs (:func:`~dualpixel.inference.view_checks.check_views`,
    :func:`~dualpixel.inference.encoding.encoding_findings`) on the first pair of every
    sequence, each finding also given as a warning: swapped, half-bright or raw views taken
    for display values would otherwise just score lower. ``synthesized``: a set ``synth``
    wrote, whose left view is the synthesizer's left, so the guess that views are exchanged
    (most blur behind the focus plane, false for a frame focused far) is not made."""
    import warnings

    from dualpixel.inference.encoding import encoding_findings, to_model
    from dualpixel.inference.view_checks import check_views
    from dualpixel.io.images import max_level, read_rgb, read_rgb_with_depth

    found = []
    for sequence in sequences:
        first = sequence.frames[0]
        (left, bits), right = read_rgb_with_depth(first.left), read_rgb(first.right)
        combined = read_rgb(first.combined) if first.combined is not None else None
        findings = encoding_findings(left, right, encoding.encoding if encoding else "srgb")
        if encoding is not None and encoding.linear:  # checked as the model takes them
            exposed = encoding.exposed(left, right, scale=max_level(bits))
            left, right = to_model(left, right, exposed, scale=max_level(bits))
            combined = None
        for finding in findings + check_views(left, right, combined=combined,
                                              orientation_known=synthesized):
            found.append({"example": sequence.name, "code": finding.code,
                          "message": finding.message})
            warnings.warn(f"{first.left}: {finding.message}", stacklevel=2)
    return found


def draw_comparisons(examples, outputs, results, method: str, output: Path) -> None:
    """Input, model output, other methods and target side by side, with zoomed crops."""
    from dualpixel.viz.comparison import render_comparison

    by_name = {(r.name, r.method): r for r in results}
    for example in examples:
        panels = {"input": read_rgb(example.combined) if example.combined else
                  (read_rgb(example.left) + read_rgb(example.right)) / 2}
        if example.name in outputs:
            panels[method] = outputs[example.name]
        panels.update({m: read_rgb(p) for m, p in sorted(example.others.items())})
        panels["target"] = read_rgb(example.target)
        scores = {m: f"{by_name[(example.name, m)].psnr:.2f} dB" for m in panels
                  if (example.name, m) in by_name}
        render_comparison(panels, output / f"compare_{example.name.replace('/', '_')}.png",
                          title=example.name, scores=scores)
