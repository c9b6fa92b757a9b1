"""Deblurring files: which frames to read and where each output goes, then running them.

Three kinds of input, as ``dualpixel deblur`` takes them: one left/right pair (output: an image
file), two folders of frames with the same names (one sequence; output: a folder), or a
DPDD-layout dataset (its pairs or ``seq_NNN`` sequences; output: a folder). Everything that can be
checked is checked before the first frame is deblurred.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from dualpixel.data.layout import discover_dp_dataset, image_files
from dualpixel.errors import InputFileError, OutputFileError, ParameterError
from dualpixel.inference.deblur import Deblurrer
from dualpixel.io.atomic import check_writable
from dualpixel.io.images import check_image_path, read_rgb_with_depth, write_png

__all__ = ["DeblurJob", "plan_deblur_jobs", "run_deblur_jobs"]


@dataclass(frozen=True)
class DeblurJob:
    """One frame: its views and its output image."""

    left: Path
    right: Path | None
    output: Path


def _output_folder(output: Path) -> Path:
    if output.exists() and not output.is_dir():
        raise OutputFileError(output, "is a file; give a folder for a sequence or dataset")
    check_writable(output / "probe.png")
    return output


def plan_deblur_jobs(
    output: str | Path, *, left: str | Path | None = None, right: str | Path | None = None,
    dataset: str | Path | None = None, split: str = "test", needs_right: bool = True,
) -> list[list[DeblurJob]]:
    """Sequences of :class:`DeblurJob` (state is reset between sequences).

    Give ``left`` (and ``right`` when ``needs_right``) as two files or two folders, or
    ``dataset`` (DPDD layout, ``split``).
    """
    output = Path(output)
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
            jobs.append([DeblurJob(f.left, f.right, folder / f"{f.left.stem}.png")
                         for f in sequence.frames])
        _refuse_overwriting_inputs(jobs, output, folder=True)
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
    if right is not None and left.is_dir() != right.is_dir():
        kind = "a folder" if left.is_dir() else "a file"
        raise InputFileError(right, f"must be {kind}, like --left {left}")
    if not left.is_dir():
        jobs = [[DeblurJob(left, right, output)]]
        _refuse_overwriting_inputs(jobs, output, folder=False)
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
        sequence.append(DeblurJob(path, other, output / path.name))
    _refuse_overwriting_inputs([sequence], output, folder=True)
    _output_folder(output)
    return [sequence]


def _refuse_overwriting_inputs(jobs: list[list[DeblurJob]], output: Path, *, folder: bool
                               ) -> None:
    """An output that is an input, or a folder that holds one (symlinks resolved), is refused
    before any work: deblurring never overwrites the user's views."""
    inputs = {p.resolve() for sequence in jobs for job in sequence
              for p in (job.left, job.right) if p is not None}
    target = output.resolve()
    clash = (next((p for p in inputs if p.is_relative_to(target)), None) if folder
             else next((p for p in inputs if p == target), None))
    if clash is not None:
        what = "holds the input" if folder and clash != target else "is the input"
        raise OutputFileError(output, f"{what} {clash}; choose an output apart from the views")


def run_deblur_jobs(deblurrer: Deblurrer, jobs: list[list[DeblurJob]]) -> Iterator[Path]:
    """Deblur every job in order (state reset per sequence), writing each output at the input's
    bit depth; yields each written path."""
    for sequence in jobs:
        deblurrer.reset()
        for job in sequence:
            left, bits = read_rgb_with_depth(job.left)
            right = read_rgb_with_depth(job.right)[0] if job.right is not None else None
            if right is not None and right.shape != left.shape:
                raise InputFileError(job.right, f"size differs from {job.left.name} "
                                                f"({right.shape[1]}x{right.shape[0]} vs "
                                                f"{left.shape[1]}x{left.shape[0]})")
            write_png(job.output, deblurrer(left, right), bit_depth=bits)
            yield job.output
