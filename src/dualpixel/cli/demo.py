"""``dualpixel demo``: the end-to-end demo (:mod:`dualpixel.demo`)."""

from __future__ import annotations

from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, SEED, DPCommand, InputPath, OutputPath
from dualpixel.weights import DEFAULT_CHECKPOINT

_CHECKPOINT_HELP = "Checkpoint: a registry name (dualpixel models) or a .safetensors path."


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path),
              default=Path("demo-output"), help="Report folder (index.html).")
@click.option("--checkpoint", default=DEFAULT_CHECKPOINT, show_default=True, help=_CHECKPOINT_HELP)
@click.option("--left", type=InputPath(dir_okay=False, exists=True, path_type=Path),
              default=None, help="Your left view (with --right) instead of a procedural scene.")
@click.option("--right", type=InputPath(dir_okay=False, exists=True, path_type=Path),
              default=None)
@click.option("--target", type=InputPath(dir_okay=False, exists=True, path_type=Path),
              default=None, help="Sharp target of your pair, to score it.")
@click.option("--rgb", type=InputPath(dir_okay=False, exists=True, path_type=Path),
              default=None, help="Your all-in-focus frame (with --depth) to synthesise from.")
@click.option("--depth", type=InputPath(dir_okay=False, exists=True, path_type=Path),
              default=None, help="Its depth map (.npy metres, or 16-bit PNG x --depth-scale).")
@click.option("--depth-scale", type=float, default=0.001, help="Metres per 16-bit PNG unit.")
@click.option("--lens-set", default="dslr-840",
              help="What blurs the synthesised frames: a blur profile relative to the frame "
                   "(dslr-840) or one of the paper's camera parameter sets (set0..set4).")
@click.option("--camera", "old_lens_set", default=None, hidden=True,
              help="Old name of --lens-set (until release 0.3).")
@click.option("--frames", type=click.IntRange(1, 30), default=3, help="Procedural frames.")
@click.option("--seed", type=SEED, default=2026, help="Procedural scene seed.")
@click.option("--device", default="auto", help="auto, cpu, cuda, cuda:1, ...")
@click.option("--tile", type=int, default=None,
              help="Tile size (multiple of 16) for bounded memory; default: whole frames.")
def demo(output: Path, checkpoint: str, left, right, target, rgb, depth, depth_scale: float,
         lens_set: str, old_lens_set: str | None, frames: int, seed: int, device: str,
         tile: int | None) -> None:
    """Synthesise, deblur with the shipped model, evaluate, and write an HTML report."""
    from dualpixel.demo import run_demo
    from dualpixel.names import warn_renamed

    if old_lens_set is not None:
        warn_renamed("--camera", "--lens-set")
        lens_set = old_lens_set
    result = run_demo(output, checkpoint=checkpoint, left=left, right=right, target=target,
                      rgb=rgb, depth=depth, depth_scale=depth_scale, lens_set=lens_set,
                      frames=frames, seed=seed, device=device, tile=tile)
    mean = result.metrics.get("mean")
    if mean:
        click.echo(f"PSNR input {mean['combined']['psnr']:.2f} dB -> output "
                   f"{mean['output']['psnr']:.2f} dB (mean over frames)")
    click.echo(f"report: {result.report.resolve()}  ({result.seconds:.1f} s)")


COMMANDS = (demo,)
