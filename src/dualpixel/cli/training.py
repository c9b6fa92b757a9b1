"""``dualpixel models`` and ``dualpixel train``."""

from __future__ import annotations

import os
from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, InputPath, OutputPath


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--width", type=float, default=1.0, help="Width multiplier of every layer.")
def models(width: float) -> None:
    """List the networks with their inputs and parameter counts."""
    from dualpixel.models import (
        ARCHITECTURES,
        MODELS,
        build_architecture,
        build_model,
        count_parameters,
    )

    click.echo(f"{'name':<15}{'inputs':<8}{'recurrent':<11}{'parameters':>12}  description")
    for name, spec in MODELS.items():
        count = count_parameters(build_model(name, width=width))
        click.echo(f"{name:<15}{spec.in_channels:<8}{'yes' if spec.recurrent else 'no':<11}"
                   f"{count:>12,}  {spec.description}")
    if width == 1.0:
        keras = count_parameters(build_model("rdpd", peepholes=False))
        click.echo(f"(rdpd without peepholes, as the authors' Keras ConvLSTM2D: {keras:,})")
    click.echo("\narchitectures (a recipe's `architecture:`):")
    for name, settings in ARCHITECTURES.items():
        described = ", ".join(f"{k} {v}" for k, v in settings.items() if k != "model")
        count = count_parameters(build_architecture(name))
        click.echo(f"  {name}: {settings['model']}, {described}, {count:,} parameters")
    from dualpixel.weights import DEPRECATED, model_info

    click.echo("\nshipped weights and presets (dualpixel.load_model(NAME), --checkpoint NAME):")
    for tag, info in model_info().items():
        aliases = f" (alias {', '.join(info['aliases'])})" if info["aliases"] else ""
        if "preset_of" in info:
            aliases = f" (preset: {info['preset_of']} with its own settings)"
        click.echo(f"  {tag}{aliases}: {info['description']}")
        refiner = f", refiner {info['refiner']}" if info["refiner"] else ""
        fused = info["output"]["fuse_frames"]
        frames = (f"temporal: each frame fused with up to {fused - 1} earlier ones" if fused > 1
                  else "temporal: carries its state along a sequence's frames"
                  if info["temporal"] else "single frames: each frame afresh")
        click.echo(f"    {info['model']} width {info['width']:g}, residual {info['residual']}"
                   f"{refiner}, {frames}, {info['parameters']:,} parameters, "
                   f"{info['bytes'] / 1e6:.1f} MB, "
                   f"sha256 {info['sha256'][:16]}...; made by recipes/{info['recipe']} phase "
                   f"{info['phase']}")
        options = {k.replace("_", "-"): v for k, v in info["output"].items()}
        settings = ", ".join(f"--{k} {v}" if not isinstance(v, bool) else
                             f"--{'' if v else 'no-'}{k}" for k, v in options.items())
        click.echo(f"    runs with {settings} unless told")
        for dataset, scores in info["metrics"].items():
            click.echo(f"    {dataset}: {scores['psnr']:.2f} dB PSNR, SSIM {scores['ssim']:.3f} "
                       f"(input {scores['input_psnr']:.2f} dB)")
    click.echo(f"retired names (asking for one says how to make it again): "
               f"{', '.join(DEPRECATED)}")


def _overrides(_ctx, _param, values: tuple[str, ...]) -> dict[str, str]:
    result = {}
    for item in values:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise click.BadParameter(f"expected KEY=VALUE, got {item!r}")
        result[key.strip().replace("-", "_")] = value
    return result


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--config", "config_path", type=InputPath(dir_okay=False, path_type=Path),
              default=None, help="YAML/JSON config (keys of dualpixel.training.TrainConfig).")
@click.option("--set", "overrides", multiple=True, callback=_overrides, metavar="KEY=VALUE",
              help="Override a config key (repeatable), e.g. --set epochs=10.")
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Run folder: config, checkpoints, history, TensorBoard logs.")
@click.option("--resume", is_flag=True, help="Continue the run in --output after its last epoch.")
@click.option("--progress/--no-progress", default=True, help="Show a progress bar.")
def train(config_path: Path | None, overrides: dict[str, str], output: Path, resume: bool,
          progress: bool) -> None:
    """Train a deblurring network (paper Sec. 5).

    Multi-GPU: torchrun --nproc-per-node N -m dualpixel train ...
    """
    from dualpixel.training import load_config
    from dualpixel.training import train as run_training

    config = load_config(config_path, overrides)
    result = run_training(config, output, resume=resume, progress=progress)
    if os.environ.get("RANK", "0") != "0":  # torchrun: one report
        return
    best = "n/a" if result.best_psnr is None else f"{result.best_psnr:.2f} dB"
    click.echo(f"trained {result.step} steps; best validation PSNR {best}; run in {output}")


COMMANDS = (models, train)
