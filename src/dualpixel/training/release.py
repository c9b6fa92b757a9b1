"""From a finished recipe run to a shipped model (``dualpixel release RUN --tag TAG``).

The weights ``reproduce`` exported for the recipe's ``ship`` block (``RUN/ship/TAG.safetensors``)
go into the package's weights folder under their tag, with a header written here: tag, recipe,
phase, start, doc, parameter count, metrics and output settings. The registry gets the row
(:mod:`dualpixel.weights`); a tag it replaces moves to the deprecation map with the recipe and
phase that remake it, and its file leaves the package; the run's per-image results become
``docs/results/TAG.csv``.

A start is where the shipped phase began: a phase of the same recipe or a shipped tag, each with
the sha256 of those weights, never a path. A tag is written once: an existing tag, a start that
resolves to nothing or a run that has not finished is refused before anything is written. The
registry is written last, so an interrupted release leaves the package as it was (a stray new
file at most, replaced by the next try).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.documents import read_mapping
from dualpixel.io.paths import check_plain_name

__all__ = ["Release", "release_run", "results_rows", "run_recipe"]

#: Columns of ``docs/results/TAG.csv``: one row per evaluation entry and image.
RESULT_COLUMNS = ("evaluation", "image", "input_psnr", "psnr", "ssim", "input_ssim")


@dataclass(frozen=True)
class Release:
    """What :func:`release_run` wrote."""

    tag: str
    weights: Path
    sha256: str
    results: Path | None
    replaced: tuple[str, ...]


def run_recipe(run: str | Path):
    """The :class:`~dualpixel.training.recipe.Recipe` a run folder was made by (its
    ``recipe.json``)."""
    from dualpixel.training.recipe import load_recipe

    marker = Path(run) / "recipe.json"
    if not marker.is_file():
        raise InputFileError(run, "is no recipe run folder (no recipe.json; "
                                  "`dualpixel reproduce RECIPE --output RUN` makes one)")
    record = read_mapping(marker, "run folder's recipe record")
    path = Path(str(record.get("recipe", "")))
    if not path.is_file():
        raise InputFileError(marker, f"names recipe {str(path)[:200]!r}, which is not a file "
                                     "(run from the folder reproduce ran in)")
    recipe = load_recipe(path)
    if recipe.name != record.get("name"):
        raise InputFileError(marker, f"was made by recipe {record.get('name')!r}, but "
                                     f"{path} is now {recipe.name!r}")
    return recipe


def _start(recipe, index: int, run: Path, registry: dict[str, Any]) -> dict[str, str] | None:
    """The shipped phase's start: ``{"phase": NAME, "sha256"}`` or ``{"tag": TAG, "sha256"}``
    (None: from nothing), checked against the run's record of it."""
    phase = recipe.phases[index]
    folder = recipe.phase_folder(run, index)
    record_path = folder / "init.json"
    record = read_mapping(record_path, "starting weights record") if record_path.is_file() else None
    if phase.init == "none":
        if record is not None:
            raise InputFileError(record_path, f"phase {phase.name} starts from nothing in the "
                                              "recipe, but its run started from weights")
        return None
    if record is None or not isinstance(record.get("sha256"), str):
        raise InputFileError(folder, f"phase {phase.name} has no record of its start "
                                     "(init.json); the start resolves to nothing")
    name, sha256 = str(record.get("name", "")), record["sha256"]
    rows = registry["weights"]
    named = registry.get("aliases", {}).get(phase.init, phase.init)
    if name in rows and name != named:  # another shipped tag than the recipe's start
        raise InputFileError(record_path, f"phase {phase.name} started from {name}, but the "
                                          f"recipe starts it from {phase.init}; the start "
                                          "resolves to nothing the recipe names")
    if name in rows or (phase.init != "previous" and phase.init == name):
        if name not in rows or rows[name]["sha256"] != sha256:
            raise InputFileError(record_path, f"the start {name!r} is no shipped tag with this "
                                              "sha256; the start resolves to nothing")
        return {"tag": name, "sha256": sha256}
    previous = recipe.phases[index - 1].name if index else None
    expected = Path("phases") / str(previous) / "last.safetensors"
    if phase.init != "previous" or not name.endswith(str(expected)):
        raise InputFileError(record_path, f"the start {name[:200]!r} is neither a shipped tag nor "
                                          f"phase {previous} of this recipe; the start "
                                          "resolves to nothing")
    return {"phase": str(previous), "sha256": sha256}


def _architecture(meta: dict[str, Any]) -> str:
    """The name in :data:`~dualpixel.models.spec.ARCHITECTURES` of a file's network: the one
    whose model, width, refiner and build options (each at ``build_model``'s default where the
    architecture does not set it) are the file's."""
    from dualpixel.models.spec import ARCHITECTURES

    options = {"residual": False, "head_relu": True, "conv_bottleneck": False}
    for name, spec in ARCHITECTURES.items():
        if (spec["model"] == meta["model"] and float(spec["width"]) == float(meta["width"])
                and all(bool(spec.get(key, default)) == bool(meta.get(key, default))
                        for key, default in options.items())
                and list(spec.get("refiner", ())) == list(meta.get("refiner") or [])):
            return name
    described = ", ".join([meta["model"], f"width {meta['width']}",
                           f"refiner {list(meta.get('refiner') or [])}",
                           *(f"{key} {meta.get(key, default)}"
                             for key, default in options.items())])
    raise ParameterError(f"the network ({described}) has no architecture name; add it to "
                         "dualpixel.models.spec.ARCHITECTURES")


def results_rows(recipe, run: Path) -> list[dict[str, Any]]:
    """Per image of every ``evaluate`` entry the run scored: input and model PSNR / SSIM."""
    rows = []
    for entry in recipe.evaluate:
        table = Path(run) / "eval" / entry["name"] / "per_image.csv"
        if not table.is_file():
            continue
        by_image: dict[str, dict[str, Any]] = {}
        with open(table, newline="") as handle:
            for row in csv.DictReader(handle):
                image = by_image.setdefault(row["name"], {"evaluation": entry["name"],
                                                          "image": row["name"]})
                if row["method"] == "input":
                    image["input_psnr"], image["input_ssim"] = row["psnr"], row["ssim"]
                elif row["method"] == "model":
                    image["psnr"], image["ssim"] = row["psnr"], row["ssim"]
        for image in by_image.values():
            rows.append({k: (round(float(image[k]), 4) if k not in ("evaluation", "image")
                             else image[k]) for k in RESULT_COLUMNS if k in image})
    return rows


def _registry_metrics(extra: dict[str, Any]) -> dict[str, dict[str, float]]:
    """The run's metrics (``{entry: {input: {...}, model: {...}}}``) as registry rows."""
    metrics = {}
    for name, scores in (extra.get("metrics") or {}).items():
        if "model" in scores and "input" in scores:
            metrics[name] = {"psnr": round(scores["model"]["psnr"], 2),
                             "ssim": round(scores["model"]["ssim"], 3),
                             "input_psnr": round(scores["input"]["psnr"], 2)}
    return metrics


def _write_json(path: Path, value: Any) -> None:
    from dualpixel.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(value, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")


def _checked_registry(path: Path) -> dict:
    """A weights registry read for writing: its tables present and mappings, and every tag and
    alias in them a plain name (a tag becomes ``TAG.safetensors`` in its folder, so a
    hand-edited ``../x`` would reach outside it); an error names the file and the entry."""
    registry = read_mapping(path, "weights registry")
    if "weights" not in registry:
        raise InputFileError(path, "has no 'weights' table: not a weights registry")
    for table in ("weights", "deprecated", "aliases", "presets"):
        if not isinstance(registry.get(table, {}), dict):
            raise InputFileError(path, f"its {table!r} entry must be a table of tags")
        registry.setdefault(table, {})
        for name in registry[table]:
            try:
                check_plain_name(str(name), f"{table} entry")
            except ParameterError as error:
                raise InputFileError(path, str(error)) from None
    return registry


def release_run(run: str | Path, tag: str, *, weights_dir: str | Path | None = None,
                results_dir: str | Path | None = Path("docs/results"),
                recipes_dir: str | Path = Path("recipes"), alias: str | None = None,
                replaces: str | Sequence[str] = (), default: bool = False) -> Release:
    """Ship run ``run``'s weights under ``tag`` (the recipe's ``ship.tag``) into
    ``weights_dir`` (the package's, :func:`~dualpixel.weights.weights_folder`, by default),
    whose ``registry.json`` gets the row; ``alias`` then names it, ``default`` makes that
    alias the default, ``replaces`` retires shipped tags and their aliases (other than
    ``alias``), each saying which recipe phase remakes it and what to use instead. The
    recipe must lie in ``recipes_dir``: a shipped model is remade from there. Per-image results
    go to ``results_dir/TAG.csv`` (None: not written)."""
    from dualpixel.io.atomic import atomic_path
    from dualpixel.models.checkpoint import load_model, read_metadata, save_model
    from dualpixel.training.recipe import phase_finished
    from dualpixel.weights import file_sha256, weights_folder

    run = Path(run)
    recipe = run_recipe(run)
    if not recipe.ship:
        raise InputFileError(recipe.path, "has no ship block: nothing to release")
    if tag != recipe.shipped_tag:
        raise ParameterError(f"--tag {tag}: the recipe {recipe.path.name} ships "
                             f"{recipe.shipped_tag}")
    if recipe.path.resolve().parent != Path(recipes_dir).resolve():
        raise InputFileError(recipe.path, f"a shipped model's recipe lives in {recipes_dir}/ "
                                          "(move it there, then release)")
    folder = Path(weights_dir) if weights_dir is not None else weights_folder()
    registry_path = folder / "registry.json"
    registry = _checked_registry(registry_path)
    names = {*registry["weights"], *registry["deprecated"], *registry["aliases"],
             *registry["presets"]}
    if tag in names:
        raise ParameterError(f"--tag {tag} already exists in {registry_path}: a tag is "
                             "written once (take the next vN)")
    replaces = (replaces,) if isinstance(replaces, str) else tuple(dict.fromkeys(replaces))
    for old in replaces:
        if old not in registry["weights"]:
            raise ParameterError(f"--replaces {old}: no shipped tag of that name")
        using = [name for name, row in registry["presets"].items()
                 if isinstance(row, dict) and row.get("weights") == old]
        if using:
            raise ParameterError(f"--replaces {old}: the preset(s) {', '.join(using)} run those "
                                 f"weights; point them at other weights in {registry_path} first")
    if alias is not None and (alias in registry["weights"] or alias in registry["deprecated"]
                              or alias in registry["presets"] or ".v" in alias):
        raise ParameterError(f"--alias {alias}: an alias is a name without .vN that is no tag")
    if default and alias is None:
        raise ParameterError("--default needs --alias (the default is an alias)")
    index = recipe.phase_index(recipe.shipped_phase)
    if not phase_finished(recipe, index, run):
        raise InputFileError(recipe.phase_folder(run, index), f"phase {recipe.shipped_phase} "
                             "has not finished; run reproduce to the end first")
    exported = run / "ship" / f"{tag}.safetensors"
    if not exported.is_file():
        raise InputFileError(exported, "missing: run reproduce to the end (it exports and "
                                       "scores the weights) first")
    start = _start(recipe, index, run, registry)
    meta = read_metadata(exported)
    extra = meta["extra"]
    if extra.get("phase") != recipe.shipped_phase:
        raise InputFileError(exported, f"was exported from phase {extra.get('phase')!r}, not "
                                       f"{recipe.shipped_phase}; rerun reproduce")
    metrics = _registry_metrics(extra)
    header = {"tag": tag, "doc": str(recipe.ship.get("doc", recipe.description)),
              "recipe": recipe.path.name, "phase": recipe.shipped_phase, "start": start,
              "num_params": extra["num_params"], "metrics": metrics,
              "output": recipe.output_settings, "config": extra.get("config")}
    target = folder / f"{tag}.safetensors"
    import torch

    save_model(target, load_model(exported), dtype=torch.float16, extra=header)
    sha256 = file_sha256(target)
    results = None
    rows = results_rows(recipe, run)
    if results_dir is not None and rows:
        results = Path(results_dir) / f"{tag}.csv"
        results.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(results) as tmp, open(tmp, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=RESULT_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
    registry["weights"][tag] = {
        "file": target.name, "architecture": _architecture(meta), "sha256": sha256,
        "recipe": recipe.path.name, "phase": recipe.shipped_phase, "start": start,
        "num_params": extra["num_params"], "doc": header["doc"], "metrics": metrics,
        "output": recipe.output_settings}
    for old_tag in replaces:  # retired with its aliases (but --alias), saying what remakes it
        old = registry["weights"].pop(old_tag)
        retired = {"recipe": old["recipe"], "phase": old["phase"], "note": f"replaced by {tag}",
                   "use": alias or tag, "sha256": old["sha256"]}
        registry["deprecated"][old_tag] = retired
        for name in [a for a, t in registry["aliases"].items() if t == old_tag]:
            del registry["aliases"][name]
            if name != alias:
                registry["deprecated"][name] = retired
    if alias is not None:
        registry["aliases"][alias] = tag
    if default:
        registry["default"] = alias
    _write_json(registry_path, registry)
    for old_tag in replaces:
        (folder / f"{old_tag}.safetensors").unlink(missing_ok=True)
    return Release(tag, target, sha256, results, replaces)
