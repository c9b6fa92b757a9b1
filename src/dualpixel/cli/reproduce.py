"""``dualpixel reproduce``: make a model from its recipe (``recipes/NAME.yaml``);
``dualpixel release``: ship what a finished run made."""

from __future__ import annotations

from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, InputPath, OutputPath
from dualpixel.names import RENDER_ON


def _tag_files(_ctx, _param, values: tuple[str, ...]) -> dict[str, Path]:
    files = {}
    for item in values:
        tag, sep, path = item.partition("=")
        if not sep or not tag.strip() or not path:
            raise click.BadParameter(f"expected TAG=PATH, got {item!r}")
        files[tag.strip()] = Path(path)
    return files


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.argument("recipe_path", metavar="RECIPE", type=InputPath(dir_okay=False, path_type=Path))
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Run folder: data/, phases/, ship/, eval/ (a rerun resumes it).")
@click.option("--until", default=None, metavar="PHASE",
              help="Stop after this phase (its weights: OUTPUT/phases/PHASE/last.safetensors).")
@click.option("--from", "start", default=None, metavar="PHASE",
              help="Start at this phase; the one before it comes from OUTPUT or, where it "
                   "ships, from its tagged weights.")
@click.option("--tag-file", "tag_files", multiple=True, callback=_tag_files, metavar="TAG=PATH",
              help="Weights for a tag a phase starts from (init: TAG), in place of the shipped "
                   "file: a tag that no longer ships, remade by its recipe, or a copy; "
                   "repeatable.")
@click.option("--dry-run", is_flag=True, help="Check every step and phase and print the plan.")
@click.option("--workers", type=click.IntRange(1), default=2,
              help="Parallel processes for the data steps (the data do not depend on it).")
@click.option("--loader-workers", type=click.IntRange(0, 256), default=None,
              help="Loader processes per training phase (0: in the main process) "
                   "[default: the training default, 2].")
@click.option("--threads", type=click.IntRange(1, 1024), default=None,
              help="PyTorch CPU threads for training [default: PyTorch's].")
@click.option("--device", default=None, help="Training device: auto, cpu, cuda, ... "
              "[default: auto].")
@click.option("--cache/--no-cache", default=None,
              help="Keep decoded training images in memory (per loader process) [default: no].")
@click.option("--frame-store", type=OutputPath(file_okay=False, path_type=Path), default=None,
              help="A folder of decoded frames shared by loader processes, epochs and runs "
                   "(made on first use).")
@click.option("--render-on", type=click.Choice(RENDER_ON), default=None,
              help="Where on-the-fly training frames are rendered: the loader processes (the "
                   "faster, also beside a GPU: give them the cores and a --frame-store), or "
                   "the training device, a batch at once (by each loader process where there "
                   "are some) [default: loader].")
@click.option("--checkpoint-minutes", type=click.FloatRange(0, 1e5), default=None,
              help="Also save the training state within an epoch this often, so a killed run "
                   "resumes from there [default: 20].")
@click.option("--progress/--no-progress", default=True, help="Show progress bars.")
def reproduce(recipe_path: Path, output: Path, until: str | None, start: str | None,
              tag_files: dict[str, Path], dry_run: bool, workers: int,
              loader_workers: int | None, threads: int | None,
              device: str | None, cache: bool | None, frame_store: Path | None,
              render_on: str | None, checkpoint_minutes: float | None,
              progress: bool) -> None:
    """Make a model from its recipe: data, every training phase, export and evaluation.

    The recipe says what the model is; how this machine runs it (loader processes, threads,
    device, caches) are the options here: they change the time a run takes, not its result.
    On a 2-core CPU: --loader-workers 0 --threads 2 --cache; on a GPU with 16 cores:
    --workers 14 --loader-workers 12 --frame-store runs/frame-store."""
    from dualpixel.training.recipe import (
        check_codecs,
        check_recipe,
        load_recipe,
        phase_start,
        plan_text,
        tag_file_notes,
    )
    from dualpixel.training.recipe import reproduce as run_recipe

    recipe = load_recipe(recipe_path, tag_files=tag_files)
    if until is not None:
        recipe.phase_index(until)
    first = 0 if start is None else recipe.phase_index(start)
    if dry_run:
        check_recipe(recipe, output)
        if first > 0:
            phase_start(recipe, first, output)  # as the run would
        check_codecs(recipe, output, first,
                     None if until is None else recipe.phase_index(until))
        for note in tag_file_notes(recipe):
            click.echo(note)
        click.echo(plan_text(recipe, output, until))
        click.echo("plan checked: every data step, phase and start resolves, its codecs are "
                   "installed")
        return
    machine = {"workers": loader_workers, "threads": threads, "device": device, "cache": cache,
               "frame_store": None if frame_store is None else str(frame_store),
               "render_on": render_on, "checkpoint_minutes": checkpoint_minutes}
    shipped = run_recipe(recipe, output, until=until, start=start, workers=workers,
                         progress=progress, log=click.echo,
                         machine={k: v for k, v in machine.items() if v is not None})
    click.echo(f"done: {shipped}" if shipped else f"done: phases in {output / 'phases'}")


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.argument("run", type=InputPath(file_okay=False, exists=True, path_type=Path))
@click.option("--tag", required=True,
              help="The tag the weights ship under: the recipe's ship.tag (written once).")
@click.option("--alias", default=None,
              help="A name that then stands for the tag (e.g. rdpd-light).")
@click.option("--default", "make_default", is_flag=True,
              help="Make --alias the package's default model.")
@click.option("--replaces", multiple=True, metavar="TAG",
              help="A shipped tag this one replaces: it moves to the deprecated names with the "
                   "recipe and phase that remake it, and its file leaves the package "
                   "(repeat for several).")
@click.option("--weights-dir", type=OutputPath(file_okay=False, path_type=Path), default=None,
              help="Weights folder with registry.json [default: the package's].")
@click.option("--results-dir", type=OutputPath(file_okay=False, path_type=Path),
              default=Path("docs/results"), show_default=True,
              help="Where the per-image results go (TAG.csv).")
@click.option("--recipes-dir", type=InputPath(file_okay=False, path_type=Path),
              default=Path("recipes"), show_default=True,
              help="Where shipped models' recipes live; the run's recipe must be there.")
def release(run: Path, tag: str, alias: str | None, make_default: bool,
            replaces: tuple[str, ...],
            weights_dir: Path | None, results_dir: Path, recipes_dir: Path) -> None:
    """Ship a finished `reproduce` run: its weights into the package under --tag, with a
    header and a registry row written from the run (recipe, phase, start, metrics)."""
    from dualpixel.training.release import release_run

    done = release_run(run, tag, weights_dir=weights_dir, results_dir=results_dir,
                       recipes_dir=recipes_dir, alias=alias, replaces=replaces,
                       default=make_default)
    click.echo(f"released {done.tag}: {done.weights} (sha256 {done.sha256[:16]}...)")
    if done.results is not None:
        click.echo(f"per-image results: {done.results}")
    for old in done.replaced:
        click.echo(f"{old} is retired (deprecated names)")


COMMANDS = (reproduce, release)
