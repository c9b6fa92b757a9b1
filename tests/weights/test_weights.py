"""The shipped weights as data (issue #32; after torchvision's test_schema_meta_validation)."""

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
    WEIGHTS,
    file_sha256,
    model_info,
    resolve_checkpoint,
    resolve_tag,
)

RECIPES = Path(__file__).resolve().parents[2] / "recipes"
FIELDS = ("tag", "recipe", "phase", "num_params", "doc", "metrics", "init")


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
    assert extra["metrics"] == weights.metrics
    for scores in weights.metrics.values():
        assert {"psnr", "ssim", "input_psnr"} <= set(scores)
    # the start is recorded by tag (or run folder) and hash, never by alias
    assert extra["init"]["name"] not in ALIASES
    assert re.fullmatch(r"[0-9a-f]{64}", extra["init"]["sha256"])
    # its architecture has a name, and builds the network the file holds
    named = build_architecture(weights.architecture)
    assert count_parameters(named) == weights.num_params
    assert named.state_dict().keys() == load_model(weights.path).state_dict().keys()
    # the recipe and phase that made it exist
    recipe = load_recipe(RECIPES / weights.recipe)
    recipe.phase_index(weights.phase)


def test_aliases_point_at_shipped_tags_and_the_default_is_one():
    assert set(ALIASES.values()) <= set(WEIGHTS)
    assert DEFAULT_CHECKPOINT in ALIASES
    assert resolve_checkpoint(DEFAULT_CHECKPOINT) == WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].path
    assert len(WEIGHTS) <= 2


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


def test_model_info_reads_headers_only():
    info = model_info()
    assert set(info) == set(WEIGHTS)
    for tag, row in info.items():
        assert row["parameters"] == WEIGHTS[tag].num_params and row["metrics"]


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
