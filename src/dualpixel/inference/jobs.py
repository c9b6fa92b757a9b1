"""Deblurring files: which frames to read and where each output goes, then running them.

Three kinds of input, as ``dualpixel deblur`` takes them: one left/right pair (output: an image
file), two folders of frames with the same names (one sequence; output: a folder), or a
DPDD-layout dataset (its pairs or ``seq_NNN`` sequences; output: a folder). Everything that can be
checked is checked before the first frame is deblurred.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualpixel.data.layout import discover_dp_dataset, image_files
from dualpixel.errors import InputFileError, OutputFileError, ParameterError
from dualpixel.inference.deblur import Deblurrer
from dualpixel.inference.encoding import (
    ViewEncoding,
    deblur_encoded,
    encoding_findings,
    pair_exposed,
)
from dualpixel.inference.view_checks import ViewFinding, check_views
from dualpixel.io.atomic import check_writable
from dualpixel.io.images import (
    check_image_path,
    max_level,
    read_rgb_with_depth,
    read_view,
    read_views,
    write_png,
)
from dualpixel.io.metadata import read_metadata
from dualpixel.io.paths import check_outputs_apart

__all__ = ["DeblurJob", "plan_deblur_jobs", "run_deblur_jobs"]


@dataclass(frozen=True)
class DeblurJob:
    """One frame: its views, its combined image if known (for the input checks) and its
    output image."""

    left: Path
    right: Path | None
    output: Path
    combined: Path | None = None


def _output_folder(output: Path) -> Path:
    if output.exists() and not output.is_dir():
        raise OutputFileError(output, "is a file; give a folder for a sequence or dataset")
    check_writable(output / "probe.png")
    return output


def plan_deblur_jobs(
    output: str | Path, *, left: str | Path | None = None, right: str | Path | None = None,
    dataset: str | Path | None = None, split: str = "test", needs_right: bool = True,
    combined: str | Path | None = None,
) -> list[list[DeblurJob]]:
    """Sequences of :class:`DeblurJob` (state is reset between sequences).

    Give ``left`` (and ``right`` when ``needs_right``) as two files or two folders, or
    ``dataset`` (DPDD layout, ``split``; its combined images are found there). ``combined``:
    with ``left``, the combined image (or a folder of them, same names), read only to check
    the views against it.
    """
    output = Path(output)
    if combined is not None and dataset is not None:
        raise ParameterError("--combined goes with --left/--right; a dataset's combined images "
                             "are found in it")
    if (dataset is None) == (left is None):
        raise ParameterError("give left and right views (--left/--right) or a dataset (--input)")
    if dataset is not None:
        sequences = discover_dp_dataset(dataset, split, require_target=False)
        # pairs go straight into the folder; sequences (and one-frame sequences whose frame
        # names repeat, as synthetic seq_NNN/frame_0000) into a folder each
        names = [f.left.stem for s in sequences if len(s.frames) == 1 for f in s.frames]
        own_folder = len(set(names)) < len(names)
        jobs = []
        for sequence in sequences:
            single = len(sequence.frames) == 1 and not own_folder
            folder = output if single else output / sequence.name
            jobs.append([DeblurJob(f.left, f.right, folder / f"{f.left.stem}.png", f.combined)
                         for f in sequence.frames])
        _refuse_overwriting_inputs(jobs, output)
        _output_folder(output)
        return jobs
    left = Path(left)
    right = None if right is None else Path(right)
    if right is None and needs_right:
        raise ParameterError("--right is required: this model reads both views")
    if not left.exists():
        raise InputFileError(left, "not found")
    if right is not None and not right.exists():
        raise InputFileError(right, "not found")
    if right is not None and left.resolve() == right.resolve():
        raise InputFileError(right, f"is --left too ({left}): give the two views of a capture, "
                                    "each from its own file or folder")
    if right is not None and left.is_dir() != right.is_dir():
        kind = "a folder" if left.is_dir() else "a file"
        raise InputFileError(right, f"must be {kind}, like --left {left}")
    combined = None if combined is None else Path(combined)
    if combined is not None and combined.is_dir() != left.is_dir():
        kind = "a folder" if left.is_dir() else "a file"
        raise InputFileError(combined, f"must be {kind}, like --left {left}")
    if not left.is_dir():
        jobs = [[DeblurJob(left, right, output, combined)]]
        _refuse_overwriting_inputs(jobs, output)
        check_writable(check_image_path(output))
        return jobs
    lefts = list(image_files(left).values())
    if not lefts:
        raise InputFileError(left, "no images found")
    sequence = []
    for path in lefts:
        other = right / path.name if right is not None else None
        if other is not None and not other.is_file():
            raise InputFileError(other, f"right frame for {path.name} is missing")
        mean = combined / path.name if combined is not None else None
        if mean is not None and not mean.is_file():
            raise InputFileError(mean, f"combined frame for {path.name} is missing")
        sequence.append(DeblurJob(path, other, output / path.name, mean))
    check_sequence_frames([job.left for job in sequence])
    if right is not None:
        check_sequence_frames([job.right for job in sequence], gaps=False)
    _refuse_overwriting_inputs([sequence], output)
    _output_folder(output)
    return [sequence]


def check_sequence_frames(frames: list[Path], *, gaps: bool = True) -> None:
    """Refuse, before any work and naming the first offending frame, a folder of frames that
    changes size, channels (grey / colour) or bit depth mid-sequence; warn, naming the frame
    after it, where numbered frames skip a number (a recurrent model's state would bridge the
    gap; ``gaps`` False: not looked for). Read from the files' headers only."""
    import re
    import warnings

    from dualpixel.io.images import image_layout

    facts = {"size": lambda x: f"{x[1]}x{x[0]}", "channels": lambda x: f"{x[2]} channel(s)",
             "bit depth": lambda x: f"{x[3]}-bit"}
    first = image_layout(frames[0])
    for path in frames[1:]:
        layout = image_layout(path)
        for what, shown in facts.items():
            if shown(layout) != shown(first):
                raise InputFileError(path, f"{what} {shown(layout)} differs from the "
                                           f"sequence's first frame {frames[0].name} "
                                           f"({shown(first)}): one sequence is one capture")
    numbers = [re.search(r"(\d+)$", path.stem) for path in frames]
    prefixes = {path.stem[: m.start()] for path, m in zip(frames, numbers) if m}
    if gaps and all(numbers) and len(prefixes) == 1:
        values = [int(m.group(1)) for m in numbers]
        for before, (after, path) in zip(values, zip(values[1:], frames[1:])):
            if after != before + 1:
                warnings.warn(f"{path}: the frames skip from number {before} to {after}; a "
                              "temporal model carries its state, or fuses earlier frames, "
                              "across the gap", stacklevel=3)
                break


def _refuse_overwriting_inputs(jobs: list[list[DeblurJob]], output: Path) -> None:
    """An output that is an input view, or a folder that holds one (symlinks resolved), is
    refused before any work (:func:`~dualpixel.io.paths.check_outputs_apart`): deblurring never
    overwrites the user's views."""
    views = [p for sequence in jobs for job in sequence for p in (job.left, job.right)
             if p is not None]
    check_outputs_apart({"view": views}, {"--output": output})


def _same_size(path: Path, image: np.ndarray, reference: Path, shape: tuple[int, ...]) -> None:
    if image.shape != shape:
        raise InputFileError(path, f"size differs from {reference.name} ({image.shape[1]}x"
                                   f"{image.shape[0]} vs {shape[1]}x{shape[0]})")


def _check_first_frame(job: DeblurJob, left: np.ndarray, right: np.ndarray, bits: tuple[int, int],
                       *, strict: bool, report: Callable[[Path, ViewFinding], None] | None,
                       raw: tuple[np.ndarray, np.ndarray, str] | None = None) -> None:
    combined = None
    if job.combined is not None:
        combined = read_rgb_with_depth(job.combined)[0]
        _same_size(job.combined, combined, job.left, left.shape)
    findings = encoding_findings(*raw) if raw is not None else []
    for finding in [*findings, *check_views(left, right, combined=combined, bit_depths=bits)]:
        if strict:
            raise InputFileError(job.left, f"{finding.message} (--strict)")
        if report is not None:
            report(job.left, finding)


def _read_pair(job: DeblurJob) -> tuple[np.ndarray, np.ndarray | None, int, int]:
    """The job's views with their own channels (1 or 3) and bit depths; a clear error when
    they differ in size or channels."""
    if job.right is None:
        left, bits = read_view(job.left)
        return left, None, bits, bits
    left, right, (bits, right_bits) = read_views(job.left, job.right)
    return left, right, bits, right_bits


def run_deblur_jobs(
    deblurrer: Deblurrer, jobs: list[list[DeblurJob]], *, views_sum: bool = False,
    strict: bool = False, report: Callable[[Path, ViewFinding], None] | None = None,
    encoding: ViewEncoding | None = None,
) -> Iterator[Path]:
    """Deblur every job in order (state reset per sequence), writing each output at the input's
    bit depth and channel count (grey views give a grey output) with its ICC profile and EXIF
    (orientation included); yields each written path.

    The first pair of each sequence is checked (:func:`~dualpixel.inference.view_checks.
    check_views`, :func:`~dualpixel.inference.encoding.encoding_findings`): each finding goes
    to ``report(path, finding)``, or with ``strict`` stops the run with an error. ``views_sum``:
    the views sum to the combined image (a raw A/B split) and are doubled first
    (:func:`~dualpixel.inference.view_checks.views_from_sum`); it needs the right views too
    (refused before any work without them). ``encoding``: how the views store light
    (:class:`~dualpixel.inference.encoding.ViewEncoding`; display values by default); the
    output is written back in it. Linear views of a sequence take the exposure of its first
    pair (:meth:`~dualpixel.inference.encoding.ViewEncoding.exposed`).
    """
    encoding = encoding or ViewEncoding()
    if views_sum and any(job.right is None for sequence in jobs for job in sequence):
        raise ParameterError("--views-sum needs both views (the combined image is their sum): "
                             "give --right, also for a model that reads one view")
    for sequence in jobs:
        deblurrer.reset()
        for index, job in enumerate(sequence):
            left, right, bits, right_bits = _read_pair(job)
            channels, scale = left.shape[2], max_level(bits)
            raw = (left, right if right is not None else left, encoding.encoding)
            if index == 0:  # one exposure per sequence (linear views), from its first pair
                try:
                    exposed = pair_exposed(encoding, left, right, scale=scale,
                                           views_sum=views_sum)
                except ParameterError as error:  # levels that do not fit this file
                    raise InputFileError(job.left, str(error)) from None
            def inspect(model_left, model_right, job=job, raw=raw, bits=(bits, right_bits)):
                _check_first_frame(job, model_left, model_right, bits, strict=strict,
                                   report=report, raw=raw)

            output = deblur_encoded(deblurrer, left, right, exposed=exposed, scale=scale,
                                    views_sum=views_sum, inspect=inspect if index == 0 else None)
            write_png(job.output, output[..., 0] if channels == 1 else output, bit_depth=bits,
                      metadata=read_metadata(job.left))
            yield job.output
