"""The shipped weights as data (after torchvision's test_schema_meta_validation)."""

import re
from pathlib import Path

import pytest

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.models import load_model, read_metadata
from dualpixel.models.registry import build_architecture, count_parameters
from dualpixel.training.recipe import load_recipe
from dualpixel.weights import (
    ALIASES,
    DEFAULT_CHECKPOINT,
    DEPRECATED,
    PRESETS,
    WEIGHTS,
    file_sha256,
    model_info,
    output_settings,
    resolve_checkpoint,
    resolve_tag,
    run_settings,
)

ROOT = Path(__file__).resolve().parents[2]
RECIPES = ROOT / "recipes"
FIELDS = ("tag", "recipe", "phase", "num_params", "doc", "metrics")
#: Headers written before `dualpixel release` existed: they record their start as ``init``
#: (v12 by an earlier tag, v2 by a run's file); their registry rows record it as a phase.
LEGACY_HEADERS = {"rdpd-light.v12", "rdpd-wide.v2"}


@pytest.mark.parametrize("tag", sorted(WEIGHTS))
def test_schema_meta_validation(tag):
    weights = WEIGHTS[tag]
    assert re.fullmatch(r"[a-z0-9-]+\.v\d+", tag), "tags are arch.vN"
    assert weights.file == f"{tag}.safetensors"
    assert file_sha256(weights.path) == weights.sha256
    extra = read_metadata(weights.path)["extra"]
    assert all(extra.get(key) for key in FIELDS), f"{tag} lacks {set(FIELDS) - set(extra)}"
    assert extra["tag"] == tag and extra["recipe"] == weights.recipe
    assert extra["phase"] == weights.phase and extra["doc"] == weights.doc
    assert extra["num_params"] == weights.num_params == count_parameters(load_model(weights.path))
    if tag not in LEGACY_HEADERS:  # older headers: measured before their output settings
        assert extra["metrics"] == weights.metrics
    for scores in weights.metrics.values():
        assert {"psnr", "ssim", "input_psnr"} <= set(scores)
    # the start: the header's is the row's (older headers: the same weights, by hash)
    if tag in LEGACY_HEADERS:
        assert extra["init"]["sha256"] == weights.start["sha256"]
    else:
        assert extra["start"] == weights.start and extra["output"] == weights.output
    # its architecture has a name, and builds the network the file holds
    named = build_architecture(weights.architecture)
    assert count_parameters(named) == weights.num_params
    assert named.state_dict().keys() == load_model(weights.path).state_dict().keys()
    # the recipe and phase that made it exist
    recipe = load_recipe(RECIPES / weights.recipe)
    recipe.phase_index(weights.phase)


@pytest.mark.parametrize("tag", sorted(WEIGHTS))
def test_every_row_is_what_its_recipe_ships_and_its_start_resolves(tag):
    weights = WEIGHTS[tag]
    recipe = load_recipe(RECIPES / weights.recipe)
    assert (recipe.shipped_tag, recipe.shipped_phase) == (tag, weights.phase)
    assert recipe.output_settings == weights.output
    assert recipe.ship.get("doc") == weights.doc
    index = recipe.phase_index(weights.phase)
    phase = recipe.phases[index]
    start = weights.start
    assert start is None or re.fullmatch(r"[0-9a-f]{64}", start["sha256"])
    if phase.init == "none":
        assert start is None
    elif phase.init == "previous":  # a phase of the same recipe, never a path
        assert start == {"phase": recipe.phases[index - 1].name, "sha256": start["sha256"]}
    else:  # a tag, shipped (hash checked) or retired with the recipe phase that remakes it
        assert start == {"tag": phase.init, "sha256": start["sha256"]}
        if phase.init in WEIGHTS:
            assert WEIGHTS[phase.init].sha256 == start["sha256"]
            resolve_tag(phase.init)
        else:
            entry = DEPRECATED[phase.init]
            load_recipe(RECIPES / entry["recipe"]).phase_index(entry["phase"])


@pytest.mark.parametrize("tag", sorted(WEIGHTS))
def test_reproduce_plans_the_registry_phase(tag, tmp_path):
    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    weights = WEIGHTS[tag]
    recipe = load_recipe(RECIPES / weights.recipe)
    # a start that no longer ships is remade by its own recipe: the default's file stands in
    remade = [f"--tag-file={retired}={WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].path}"
              for retired in recipe.start_tags if retired in DEPRECATED]
    result = CliRunner().invoke(cli, ["reproduce", str(RECIPES / weights.recipe), "--output",
                                      str(tmp_path / "run"), "--dry-run", *remade])
    assert result.exit_code == 0, result.output
    assert f"ship: {tag} from phase {weights.phase} (float16" in result.output


def test_aliases_point_at_shipped_tags_and_the_default_is_one():
    assert set(ALIASES.values()) <= set(WEIGHTS)
    assert DEFAULT_CHECKPOINT in ALIASES
    assert resolve_checkpoint(DEFAULT_CHECKPOINT) == WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].path
    # the default, the tag it was fine-tuned from (its recipe's start) and one alternative
    assert len(WEIGHTS) <= 3


def test_a_retired_name_says_which_recipe_phase_remakes_it():
    assert not set(DEPRECATED) & (set(WEIGHTS) | set(ALIASES))
    for name, entry in DEPRECATED.items():
        with pytest.raises(InputFileError, match="retired checkpoint") as caught:
            resolve_checkpoint(name)
        if entry["phase"]:
            assert f"reproduce recipes/{entry['recipe']} --output DIR --until {entry['phase']}" \
                in str(caught.value)
            load_recipe(RECIPES / entry["recipe"]).phase_index(entry["phase"])


def test_tags_are_checked_and_aliases_are_no_tags(tmp_path):
    tag = ALIASES[DEFAULT_CHECKPOINT]
    assert resolve_tag(tag) == WEIGHTS[tag].path
    with pytest.raises(ParameterError, match="is an alias"):
        resolve_tag(DEFAULT_CHECKPOINT)
    with pytest.raises(ParameterError, match="no shipped weights tagged"):
        resolve_tag("rdpd-light.v999")


def test_presets_run_shipped_weights_with_their_own_settings():
    """A preset (``rdpd-light-video``) names shipped weights and settings over theirs: it
    loads their file, runs with both, is listed as temporal when it fuses frames, and its name
    is no tag, alias or retired name."""
    assert "rdpd-light-video" in PRESETS
    assert not set(PRESETS) & (set(WEIGHTS) | set(ALIASES) | set(DEPRECATED))
    info = model_info()
    for name, preset in PRESETS.items():
        assert preset.weights in WEIGHTS and preset.doc and preset.output
        assert resolve_checkpoint(name) == WEIGHTS[preset.weights].path
        assert output_settings(name) == {**WEIGHTS[preset.weights].output, **preset.output}
        assert run_settings(name, fuse_frames=1)["fuse_frames"] == 1
        assert info[name]["preset_of"] == preset.weights
        assert info[name]["temporal"] == (output_settings(name).get("fuse_frames", 1) > 1)
        for scores in preset.metrics.values():
            assert scores["psnr"] > scores["input_psnr"]
    assert run_settings("rdpd-light-video")["fuse_frames"] == 6
    assert run_settings("rdpd-light-video")["brightness"] == "tied"
    with pytest.raises(ParameterError, match="no shipped weights tagged"):
        resolve_tag("rdpd-light-video")  # a recipe starts from weights, not from a preset


def test_model_info_reads_headers_only():
    info = model_info()
    assert set(info) == set(WEIGHTS) | set(PRESETS)
    for tag, row in info.items():
        weights = WEIGHTS[PRESETS[tag].weights if tag in PRESETS else tag]
        assert row["parameters"] == weights.num_params and row["metrics"]


@pytest.mark.parametrize("name", sorted(DEPRECATED))
def test_retired_names_say_what_to_do_once(name):
    with pytest.raises(InputFileError) as caught:
        resolve_checkpoint(name)
    message = str(caught.value)
    note = DEPRECATED[name].get("note")
    assert f"{name} no longer ships" in message
    if note:
        assert message.count(note) == 1, message
    if DEPRECATED[name].get("use"):
        assert f"use {DEPRECATED[name]['use']} instead" in message


def test_a_shipped_model_runs_with_its_own_settings_unless_told(monkeypatch):
    import dataclasses

    import numpy as np

    import dualpixel
    from dualpixel import weights as registry
    from dualpixel.evaluation.target_free import method_settings
    from dualpixel.weights import run_settings

    tag = ALIASES[DEFAULT_CHECKPOINT]
    own = {"brightness": "tied", "overshoot": "limited"}
    monkeypatch.setitem(registry.WEIGHTS, tag, dataclasses.replace(WEIGHTS[tag], output=own))
    assert run_settings(DEFAULT_CHECKPOINT) == {**own, "flips": False, "fuse_frames": 1}
    assert run_settings(tag, brightness="model")["brightness"] == "model"  # told: as told
    assert run_settings("any/file.safetensors")["brightness"] == "model"  # a file: as given
    assert list(method_settings([DEFAULT_CHECKPOINT])) == [DEFAULT_CHECKPOINT + "+limited+tied"]
    rng = np.random.default_rng(0)
    left = rng.uniform(0.2, 0.8, (32, 48, 3)).astype(np.float32)
    right = np.roll(left, 1, axis=1)
    by_default = dualpixel.deblur(left, right, model=tag, device="cpu", precision="fp32")
    told = dualpixel.deblur(left, right, model=tag, device="cpu", precision="fp32", **own)
    plain = dualpixel.deblur(left, right, model=tag, device="cpu", precision="fp32",
                             brightness="model", overshoot="model")
    np.testing.assert_array_equal(by_default, told)
    assert np.abs(by_default - plain).max() > 1e-4


def test_synthesis_starts_from_what_the_default_model_was_trained_on(tmp_path):
    """`synth` and `synthesize()` default to SYNTH_SETTINGS["shipped"]: the lens sets, PSF
    shapes, light space and noise of one of the default model's last phase's synthetic sets
    made without a camera file, read from its recipe."""
    from dualpixel.synthesis.dataset import SYNTH_SETTINGS
    from dualpixel.training.recipe import phase_config

    weights = WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]]
    recipe = load_recipe(RECIPES / weights.recipe)
    config = phase_config(recipe, recipe.phase_index(weights.phase), tmp_path, None)
    folders = config.synthetic_data if isinstance(config.synthetic_data, list) else [
        config.synthetic_data]
    steps = {str(tmp_path / "data" / s.name): s for s in recipe.data}
    shipped = SYNTH_SETTINGS["shipped"]
    trained = [steps[str(folder)].args for folder in folders]
    assert any("camera" not in args and tuple(args["lens_sets"]) == shipped["lens_sets"]
               and all(args.get(key) == shipped[key] for key in ("psf_bank", "noise_model",
                                                                 "light"))
               and tuple(args["noise_sigmas"]) == shipped["noise_sigmas"] for args in trained)


@pytest.mark.parametrize("tag", sorted(WEIGHTS))
def test_the_registry_dev_figures_are_the_results_as_it_runs(tag):
    """Issue #73: `dualpixel models` (the registry) printed rdpd-light.v12's dev figures as
    measured before it ran tied (26.31 / 25.82) where the README and `eval` give 26.36 / 25.86:
    the registry's dev metrics are the means of the model's results CSV, to 0.01 dB."""
    import csv

    path = ROOT / "docs" / "results" / f"{tag}.csv"
    if not path.is_file():
        pytest.skip(f"no results CSV for {tag}")
    rows = list(csv.DictReader(path.open()))
    for key in ("canon-dp-real", "canon-dp-real-hd"):
        scores = [float(r["psnr"]) for r in rows if r["evaluation"] == key]
        assert len(scores) == 7 and key in WEIGHTS[tag].metrics
        assert WEIGHTS[tag].metrics[key]["psnr"] == pytest.approx(sum(scores) / 7, abs=0.005)

