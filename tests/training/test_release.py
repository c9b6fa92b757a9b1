"""``dualpixel release``: from a finished recipe run to a shipped, registered model."""

import csv
import json
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.models import load_model, read_metadata
from dualpixel.models.registry import count_parameters
from dualpixel.training.recipe import load_recipe, reproduce
from dualpixel.weights import file_sha256
from tests.training.test_recipe import TINY_MACHINE, TINY_PHASE, TINY_SCENES

TAG = "rdpd-light-base.v7"  # the tiny run's network is the rdpd-light-base architecture


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A two-phase tiny recipe in a ``recipes/`` folder, run to the end by ``reproduce``."""
    root = tmp_path_factory.mktemp("release")
    (root / "recipes").mkdir()
    raw = {
        "name": "tiny",
        "data": [{"name": "scenes", "scenes": {**TINY_SCENES, "seed": 1}},
                 {"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set1"],
                                             "max_layers": 40, "noise_sigmas": [0.01]}}],
        "train": {"model": "rdpd", "synthetic_data": "synth", "val_data": "synth",
                  "val_split": "train", **TINY_PHASE, "width": 0.5, "residual": True},
        "phases": [{"name": "first"}, {"name": "second", "set": {"learning_rate": 1e-4}}],
        "ship": {"tag": TAG, "doc": "a tiny model", "output": {"brightness": "tied"}},
        "evaluate": [{"name": "synth", "dataset": "synth", "split": "train"}],
    }
    recipe = root / "recipes" / "tiny.yaml"
    recipe.write_text(yaml.safe_dump(raw, sort_keys=False))
    reproduce(load_recipe(recipe), root / "run", workers=1, progress=False, machine=TINY_MACHINE,
              log=lambda _: None)
    return root / "run"


def _weights_folder(tmp_path: Path, run: Path) -> Path:
    """A package weights folder holding two older tags (copies of the run's export)."""
    folder = tmp_path / "weights"
    folder.mkdir()
    registry = {"default": "base", "aliases": {"base": "rdpd-light-base.v6",
                                               "old": "rdpd-light-base.v6"},
                "weights": {}, "deprecated": {}}
    for version, phase in (("v5", "first"), ("v6", "last")):
        old = folder / f"rdpd-light-base.{version}.safetensors"
        old.write_bytes((run / "ship" / f"{TAG}.safetensors").read_bytes())
        registry["weights"][f"rdpd-light-base.{version}"] = {
            "file": old.name, "architecture": "rdpd-light-base", "sha256": file_sha256(old),
            "recipe": "old.yaml", "phase": phase, "start": None, "num_params": 1, "doc": "old",
            "metrics": {}, "output": {}}
    (folder / "registry.json").write_text(json.dumps(registry))
    return folder


def _release(run: Path, weights: Path, results: Path, *extra: str, recipes: Path | None = None):
    recipes = recipes or run.parent / "recipes"
    return CliRunner().invoke(cli, ["release", str(run), "--weights-dir", str(weights),
                                    "--results-dir", str(results), "--recipes-dir",
                                    str(recipes), *extra])


def test_release_writes_the_file_header_row_deprecation_and_results(finished_run, tmp_path):
    weights = _weights_folder(tmp_path, finished_run)
    old_sha256 = file_sha256(weights / "rdpd-light-base.v6.safetensors")
    result = _release(finished_run, weights, tmp_path / "results", "--tag", TAG, "--alias",
                      "base", "--default", "--replaces", "rdpd-light-base.v6",
                      "--replaces", "rdpd-light-base.v5")
    assert result.exit_code == 0, result.output
    shipped = weights / f"{TAG}.safetensors"
    registry = json.loads((weights / "registry.json").read_text())
    row = registry["weights"][TAG]
    # the header, written by code: tag, recipe, phase, start by phase and hash, never a path
    extra = read_metadata(shipped)["extra"]
    first = finished_run / "phases" / "first" / "last.safetensors"
    start = {"phase": "first", "sha256": file_sha256(first)}
    assert extra["tag"] == TAG and extra["recipe"] == "tiny.yaml" and extra["phase"] == "second"
    assert extra["start"] == start and "init" not in extra
    assert extra["output"] == {"brightness": "tied"} and extra["doc"] == "a tiny model"
    # the row agrees with the file and the recipe
    assert row == {"file": shipped.name, "architecture": "rdpd-light-base",
                   "sha256": file_sha256(shipped), "recipe": "tiny.yaml", "phase": "second",
                   "start": start, "num_params": count_parameters(load_model(shipped)),
                   "doc": "a tiny model", "metrics": extra["metrics"],
                   "output": {"brightness": "tied"}}
    assert set(row["metrics"]["synth"]) == {"psnr", "ssim", "input_psnr"}
    # the replaced tag is retired with what remakes it and its file's hash (a recipe that starts
    # from it can tell the released file from a remade one), and so are its other aliases
    retired = {"recipe": "old.yaml", "phase": "last", "note": f"replaced by {TAG}",
               "use": "base", "sha256": old_sha256}
    assert registry["deprecated"] == {"rdpd-light-base.v6": retired, "old": retired,
                                      "rdpd-light-base.v5": {**retired, "phase": "first"}}
    assert registry["aliases"] == {"base": TAG} and registry["default"] == "base"
    assert set(registry["weights"]) == {TAG}
    assert sorted(f.name for f in weights.glob("*.safetensors")) == [shipped.name]
    assert "rdpd-light-base.v5 is retired" in result.output
    # per-image results from the run's evaluation
    with open(tmp_path / "results" / f"{TAG}.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert rows and {r["evaluation"] for r in rows} == {"synth"}
    # the run's own evaluation, image by image (not merely positive numbers)
    with open(finished_run / "eval" / "synth" / "per_image.csv", newline="") as handle:
        measured = list(csv.DictReader(handle))
    by_image = {(r["name"], r["method"]): float(r["psnr"]) for r in measured}
    assert len(rows) == len({name for name, _ in by_image})
    for row in rows:
        assert float(row["psnr"]) == pytest.approx(by_image[row["image"], "model"], abs=1e-3)
        assert float(row["input_psnr"]) == pytest.approx(by_image[row["image"], "input"],
                                                         abs=1e-3)
    assert load_model(shipped).width == 0.5


def test_release_refuses_before_writing(finished_run, tmp_path):
    weights = _weights_folder(tmp_path, finished_run)
    before = (weights / "registry.json").read_text()

    def refused(result, *words):
        assert result.exit_code != 0 and "Traceback" not in result.output, result.output
        for word in words:
            assert word in result.output, result.output
        assert (weights / "registry.json").read_text() == before
        assert not (weights / f"{TAG}.safetensors").exists()

    results = tmp_path / "results"
    refused(_release(finished_run, weights, results, "--tag", "rdpd-light-base.v8"),
            "--tag", TAG)
    refused(_release(finished_run, weights, results, "--tag", TAG, "--replaces", "nothing.v1"),
            "--replaces")
    refused(_release(finished_run, weights, results, "--tag", TAG, "--default"), "--alias")
    # weights a preset runs are not retired from under it; a preset's name is no alias
    registry = json.loads(before)
    registry["presets"] = {"base-video": {"weights": "rdpd-light-base.v6",
                                          "output": {"fuse_frames": 6}, "doc": "video"}}
    (weights / "registry.json").write_text(json.dumps(registry))
    before = (weights / "registry.json").read_text()
    refused(_release(finished_run, weights, results, "--tag", TAG, "--replaces",
                     "rdpd-light-base.v6"), "base-video", "--replaces")
    refused(_release(finished_run, weights, results, "--tag", TAG, "--alias", "base-video"),
            "--alias")
    refused(CliRunner().invoke(cli, ["release", str(finished_run), "--tag", TAG,
                                     "--weights-dir", str(weights), "--results-dir",
                                     str(results), "--recipes-dir", str(tmp_path)]),
            "recipes")
    # an existing tag is never written again
    registry = json.loads(before)
    registry["deprecated"][TAG] = {"recipe": "tiny.yaml", "phase": "second", "note": "old"}
    (weights / "registry.json").write_text(json.dumps(registry))
    before = (weights / "registry.json").read_text()
    refused(_release(finished_run, weights, results, "--tag", TAG), "already exists")


def test_a_start_that_resolves_to_nothing_or_an_unfinished_run_is_refused(finished_run,
                                                                          tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    recipes = finished_run.parent / "recipes"
    weights = _weights_folder(tmp_path, finished_run)
    record = run / "phases" / "second" / "init.json"
    good = record.read_text()
    record.write_text(json.dumps({"name": "/somewhere/else.safetensors", "sha256": "0" * 64}))
    result = _release(run, weights, tmp_path / "results", "--tag", TAG, recipes=recipes)
    assert result.exit_code == 1 and "resolves to nothing" in result.output, result.output
    shipped = weights / "rdpd-light-base.v6.safetensors"  # a shipped tag the recipe never names
    record.write_text(json.dumps({"name": "rdpd-light-base.v6", "sha256": file_sha256(shipped)}))
    result = _release(run, weights, tmp_path / "results", "--tag", TAG, recipes=recipes)
    assert result.exit_code == 1 and "started from rdpd-light-base.v6" in result.output
    assert "starts it from previous" in result.output, result.output
    record.write_text(good)
    history = run / "phases" / "second" / "history.jsonl"
    history.write_text("")
    result = _release(run, weights, tmp_path / "results", "--tag", TAG, recipes=recipes)
    assert result.exit_code == 1 and "has not finished" in result.output, result.output
    assert "Traceback" not in result.output


def test_a_run_brought_back_without_its_optimizer_state_releases(finished_run, tmp_path):
    """A run trained on another machine (a lent GPU) comes back with its weights, history and
    records but not its resume state (about 3x the weights): it is finished, and releases."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    for state in run.glob("phases/*/last_state.pt"):
        state.unlink()
    weights = _weights_folder(tmp_path, finished_run)
    result = _release(run, weights, tmp_path / "results", "--tag", TAG,
                      recipes=finished_run.parent / "recipes")
    assert result.exit_code == 0, result.output
    assert TAG in json.loads((weights / "registry.json").read_text())["weights"]
    (run / "phases" / "second" / "last.safetensors").unlink()  # no weights: not finished
    (tmp_path / "again").mkdir()
    weights = _weights_folder(tmp_path / "again", finished_run)
    result = _release(run, weights, tmp_path / "results2", "--tag", TAG,
                      recipes=finished_run.parent / "recipes")
    assert result.exit_code == 1 and "has not finished" in result.output, result.output


def test_a_hand_edited_registry_cannot_reach_outside_its_folder(finished_run, tmp_path):
    """A tag or alias that is not a plain name, or a registry without its weights table, is
    refused naming registry.json, and nothing outside --weights-dir is touched."""
    weights = _weights_folder(tmp_path, finished_run)
    registry = json.loads((weights / "registry.json").read_text())
    outside = tmp_path / "precious.safetensors"
    outside.write_bytes(b"user data")
    results = tmp_path / "results"
    for edit in (lambda r: r["weights"].update({"../precious": r["weights"][next(iter(
                     r["weights"]))]}),
                 lambda r: r["aliases"].update({"a/b": TAG}),
                 lambda r: r.pop("weights"),
                 lambda r: r.update({"aliases": ["not", "a", "table"]})):
        edited = json.loads(json.dumps(registry))
        edit(edited)
        (weights / "registry.json").write_text(json.dumps(edited))
        result = _release(finished_run, weights, results, "--tag", TAG, "--replaces",
                          "../precious")
        assert result.exit_code == 1 and "registry.json" in result.output, result.output
        assert "Traceback" not in result.output
        assert outside.read_bytes() == b"user data"
        assert not (weights / f"{TAG}.safetensors").exists()


def test_list_models_hands_out_copies():
    import dualpixel

    first = dualpixel.list_models()
    tag = next(iter(first))
    first[tag]["metrics"] = {"edited": 1.0}
    first[tag]["aliases"].append("mine")
    first.pop(tag)
    again = dualpixel.list_models()
    assert tag in again and "edited" not in again[tag].get("metrics", {})
    assert "mine" not in again[tag]["aliases"]


def test_a_network_no_architecture_names_is_refused_by_what_sets_it_apart(tmp_path):
    """A file's network is named only by an architecture that builds it exactly: the light
    RDPD with DPDNet's bottleneck in place of its ConvLSTM is not ``rdpd-light-base``, and the
    refusal says which setting sets it apart."""
    from dualpixel.errors import ParameterError
    from dualpixel.models import build_model, save_model
    from dualpixel.training.release import _architecture

    for conv_bottleneck in (False, True):
        path = tmp_path / f"{conv_bottleneck}.safetensors"
        save_model(path, build_model("rdpd", width=0.5, residual=True,
                                     conv_bottleneck=conv_bottleneck))
        if not conv_bottleneck:
            assert _architecture(read_metadata(path)) == "rdpd-light-base"
            continue
        with pytest.raises(ParameterError, match="conv_bottleneck True"):
            _architecture(read_metadata(path))
