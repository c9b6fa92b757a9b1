"""``dualpixel adapt``: a shipped model fine-tuned to a camera from its own DP photographs."""

from __future__ import annotations

from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, InputPath, OutputPath, parse_size


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.argument("pairs", nargs=-1, required=True,
                type=InputPath(file_okay=False, exists=True, path_type=Path))
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Run folder: camera, blur maps, data, training, adapted.safetensors, report "
                   "(a rerun resumes it).")
@click.option("--select", multiple=True, metavar="PATTERN",
              help="Take only the pairs whose folder name matches (repeatable; e.g. "
                   "'pixel-*') [default: every pair].")
@click.option("--checkpoint", default="rdpd-light", show_default=True,
              help="The model to adapt: a registry name or a .safetensors file.")
@click.option("--camera", default=None,
              help="The camera's file (or a shipped camera's name) [default: measured from the "
                   "pairs' views].")
@click.option("--photos", type=InputPath(file_okay=False, exists=True, path_type=Path),
              default=None, help="Photographs for the synthetic scenes [default: the package's].")
@click.option("--scenes", type=click.IntRange(2, 100_000), default=40, show_default=True,
              help="Synthetic scenes made from the photographs.")
@click.option("--epochs", type=click.IntRange(1, 10_000), default=3, show_default=True)
@click.option("--iterations", type=click.IntRange(1, 1_000_000), default=200, show_default=True,
              help="Training steps per epoch.")
@click.option("--patch-size", type=click.IntRange(64, 8192), default=192, show_default=True,
              help="Training crops (px) of the synthetic frames and of the pairs.")
@click.option("--scene-size", default="840x560", show_default=True, callback=parse_size,
              help="Synthetic scenes' size WIDTHxHEIGHT.")
@click.option("--formation-weight", type=click.FloatRange(0, 1e3), default=0.0,
              show_default=True, help="Weight of the formation loss on the pairs (0: off).")
@click.option("--in-focus-weight", type=click.FloatRange(0, 1e3), default=0.0,
              show_default=True, help="Weight of keeping their in-focus blocks (0: off).")
@click.option("--view-coding", default=None, metavar="CODEC[:SHARE]",
              help="Code the two views of a share of the synthetic training pairs lossily, as "
                   "the pairs' own views may have been: h264 (needs PyAV) or jpeg, e.g. h264:0.5 "
                   "[default: none].")
@click.option("--seed", type=click.IntRange(0, 2**31 - 1), default=0, show_default=True)
@click.option("--device", default="auto", show_default=True, help="auto, cpu, cuda, ...")
@click.option("--threads", type=click.IntRange(1, 1024), default=None,
              help="PyTorch CPU threads [default: PyTorch's].")
@click.option("--progress/--no-progress", default=True, help="Show progress bars.")
def adapt(pairs: tuple[Path, ...], output: Path, select: tuple[str, ...], checkpoint: str,
          camera: str | None, photos: Path | None, scenes: int, epochs: int, iterations: int,
          patch_size: int, scene_size: tuple[int, int], formation_weight: float,
          in_focus_weight: float, view_coding: str | None, seed: int, device: str,
          threads: int | None, progress: bool) -> None:
    """Fine-tune a model to the camera of the DP pairs in the PAIRS folders (left/right views,
    no targets needed; targets present are ignored), from synthetic data formed like that
    camera and a formation loss on the pairs themselves. Writes OUTPUT/adapted.safetensors and
    OUTPUT/report.md (before and after)."""
    from dualpixel.adaptation.finetune import AdaptSettings
    from dualpixel.adaptation.finetune import adapt as run_adapt

    settings = AdaptSettings(model=checkpoint, select=select, camera=camera,
                             photos=None if photos is None else str(photos), scenes=scenes,
                             epochs=epochs, iterations=iterations, patch_size=patch_size,
                             scene_size=scene_size,
                             formation_weight=formation_weight, in_focus_weight=in_focus_weight,
                             view_coding=view_coding, seed=seed)
    result = run_adapt(pairs, output, settings, device=device, threads=threads,
                       progress=progress, log=click.echo)
    start, adapted = result.figures["start"], result.figures["adapted"]
    click.echo(f"held-out frames of the camera: {start['camera_val_psnr']:.2f} -> "
               f"{adapted['camera_val_psnr']:.2f} dB; report: {result.report}")


COMMANDS = (adapt,)
