"""``dualpixel reproduce``: make a model from its recipe (``recipes/NAME.yaml``)."""

from __future__ import annotations

from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, OutputPath


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.argument("recipe_path", metavar="RECIPE", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Run folder: data/, phases/, ship/, eval/ (a rerun resumes it).")
@click.option("--until", default=None, metavar="PHASE",
              help="Stop after this phase (its weights: OUTPUT/phases/PHASE/last.safetensors).")
@click.option("--from", "start", default=None, metavar="PHASE",
              help="Start at this phase; the one before it comes from OUTPUT or, where it "
                   "ships, from its tagged weights.")
@click.option("--dry-run", is_flag=True, help="Check every step and phase and print the plan.")
@click.option("--workers", type=click.IntRange(1), default=2,
              help="Parallel processes for the data steps (the data do not depend on it).")
@click.option("--progress/--no-progress", default=True, help="Show progress bars.")
def reproduce(recipe_path: Path, output: Path, until: str | None, start: str | None,
              dry_run: bool, workers: int, progress: bool) -> None:
    """Make a model from its recipe: data, every training phase, export and evaluation."""
    from dualpixel.training.recipe import check_recipe, load_recipe, plan_text
    from dualpixel.training.recipe import reproduce as run_recipe

    recipe = load_recipe(recipe_path)
    if until is not None:
        recipe.phase_index(until)
    if start is not None:
        recipe.phase_index(start)
    if dry_run:
        check_recipe(recipe, output)
        click.echo(plan_text(recipe, output, until))
        click.echo("plan checked: every data step, phase and start resolves")
        return
    shipped = run_recipe(recipe, output, until=until, start=start, workers=workers,
                         progress=progress, log=click.echo)
    click.echo(f"done: {shipped}" if shipped else f"done: phases in {output / 'phases'}")


COMMANDS = (reproduce,)
