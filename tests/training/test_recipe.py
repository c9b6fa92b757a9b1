"""Recipes and ``dualpixel reproduce``."""

import json
import re
import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError
from dualpixel.models import load_model, read_metadata
from dualpixel.training.recipe import load_recipe, reproduce
from tests.conftest import write_dpdd_pairs, write_photographs

RECIPES = Path(__file__).resolve().parents[2] / "recipes"
TINY_SCENES = {"sequences": 1, "frames": 2, "width": 96, "height": 64}
TINY_PHASE = {"epochs": 1, "iterations_per_epoch": 2, "patch_size": 32, "val_limit": 1,
              "width": 0.125, "tensorboard": False, "sequence_frames": 2}
#: How the tests' machine runs a phase: reproduce's options, never a recipe's keys.
TINY_MACHINE = {"threads": 1, "workers": 0, "device": "cpu"}
MACHINE_OPTIONS = ["--threads", "1", "--loader-workers", "0", "--device", "cpu"]


def _shrunk(source: Path, folder: Path, real: Path) -> Path:
    """``source`` (its ``extends`` resolved) with tiny data and two iterations per phase,
    written into ``folder`` beside a copy of its cameras; real-data folders point at ``real``."""
    from dualpixel.training.recipe import _raw_recipe

    raw = _raw_recipe(source)
    for step in raw.get("data", []):
        if "scenes" in step:
            step["scenes"].update(TINY_SCENES)
            if "photos" in step["scenes"]:  # three small photographs of the test's own
                step["scenes"]["photos"] = str(write_photographs(folder / "photos"))
        else:
            step["synth"].update(max_layers=40)
    for section in [raw.get("train", {})] + [p.setdefault("set", {}) for p in raw["phases"]]:
        for key in ("real_data", "real_val_data"):
            if key in section and not any(section[key] == s["name"] for s in raw["data"]):
                section[key] = str(real)
    widened = False
    for phase in raw["phases"]:
        phase["set"].update(TINY_PHASE)
        widened = (widened or phase["set"].get("widen_init", raw["train"].get("widen_init"))
                   or phase.get("init", "previous") not in ("previous", "none"))
        if widened:  # the width of its start (shipped weights) or a multiple of it, kept by
            del phase["set"]["width"]  # the phases after
    for entry in raw.get("evaluate", []):
        if not any(entry["dataset"] == s["name"] for s in raw["data"]):
            entry["dataset"] = str(real)
    if (source.parent / "cameras").is_dir():
        shutil.copytree(source.parent / "cameras", folder / "cameras", dirs_exist_ok=True)
    path = folder / source.name
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def real_pairs(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("dpdd")
    for split in ("train", "test"):
        write_dpdd_pairs(root, split, ["a", "b"], size=(64, 96))
    return root


@pytest.mark.parametrize("name", sorted(p.name for p in RECIPES.glob("*.yaml")))
def test_every_recipe_runs_end_to_end_on_tiny_data(name, tmp_path, real_pairs):
    """Every shipped recipe, shrunk; a start whose tag no longer ships is given the default's
    file (the same network) as ``--tag-file`` gives a remade one."""
    from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, DEPRECATED, WEIGHTS

    path = _shrunk(RECIPES / name, tmp_path, real_pairs)
    default = WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].path
    retired = [p.init for p in load_recipe(path).phases if p.init in DEPRECATED]
    recipe = load_recipe(path, tag_files={tag: default for tag in retired})
    shipped = reproduce(recipe, tmp_path / "run", workers=1, progress=False, machine=TINY_MACHINE,
                        log=lambda _: None)
    extra = read_metadata(shipped)["extra"]
    last = recipe.phases[-1].name
    assert extra["recipe"] == name and extra["phase"] == recipe.ship.get("phase", last)
    assert extra["num_params"] > 0 and set(extra["metrics"]) <= {e["name"] for e in
                                                                  recipe.evaluate}
    load_model(shipped)
    for index, phase in enumerate(recipe.phases):
        history = (recipe.phase_folder(tmp_path / "run", index) / "history.jsonl").read_text()
        assert json.loads(history.splitlines()[-1])["step"] == 2, phase.name
        init = read_metadata(recipe.phase_folder(tmp_path / "run", index)
                             / "last.safetensors")["extra"]["init"]
        if phase.init == "none":
            assert init is None
        else:  # the start by name and hash, never by alias
            assert len(init["sha256"]) == 64 and not init["name"].startswith("rdpd-light/")


@pytest.mark.parametrize("path", sorted((RECIPES.parent / "experiments" / "recipes").glob(
    "*.yaml")), ids=lambda p: p.name)
def test_experiment_recipes_resolve(path, tmp_path):
    """Variants kept under experiments/ (measured, not shipped) still name valid settings,
    camera files and starts (a retired start: one its own recipe remakes)."""
    from dualpixel.training.recipe import check_recipe

    check_recipe(load_recipe(path), tmp_path / "run", retired_starts=True)  # remade by theirs


def _tiny_recipe(tmp_path: Path, **changes) -> Path:
    raw = {
        "name": "tiny",
        "description": "a tiny model",
        "data": [
            {"name": "scenes", "scenes": {**TINY_SCENES, "seed": 1}},
            {"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set1"],
                                        "max_layers": 40, "noise_sigmas": [0.01]}},
        ],
        "train": {"model": "rdpd", "synthetic_data": "synth", "val_data": "synth",
                  "val_split": "train", "sequence_frames": 2, **TINY_PHASE},
        "phases": [{"name": "first", "set": {"learning_rate": 1e-3}},
                   {"name": "second", "set": {"refiner": [4, 8]}}],
        "ship": {"tag": "tiny.v1", "doc": "a tiny model"},
        "evaluate": [{"name": "synth", "dataset": "synth", "split": "train"}],
    }
    for key, value in changes.items():
        raw[key] = value
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_reproduce_resumes_refuses_other_recipes_and_runs_until_a_phase(tmp_path):
    recipe_path = _tiny_recipe(tmp_path)
    out = tmp_path / "run"
    runner = CliRunner()
    result = runner.invoke(cli, ["reproduce", str(recipe_path), "--output", str(out),
                                 "--until", "first", "--no-progress", *MACHINE_OPTIONS])
    assert result.exit_code == 0, result.output
    assert (out / "phases/first/last.safetensors").is_file()
    assert not (out / "phases/second").exists()
    # where the run stands: each data step and phase numbered, with the time so far
    assert re.search(r"\[data 2/2, 0:\d\d:\d\d\] synth: synth", result.output), result.output
    assert re.search(r"\[phase 1/1, 0:00:00 into the phases\] first", result.output)
    assert re.search(r"phases done in 0:\d\d:\d\d", result.output)
    stamp = (out / "phases/first/last.safetensors").stat().st_mtime_ns
    dry = runner.invoke(cli, ["reproduce", str(recipe_path), "--output", str(out), "--dry-run"])
    assert dry.exit_code == 0, dry.output
    assert "first" in dry.output and "[done]" in dry.output and "second" in dry.output
    assert "to do" in dry.output and "plan checked" in dry.output
    result = runner.invoke(cli, ["reproduce", str(recipe_path), "--output", str(out),
                                 "--no-progress", "--threads", "2", "--cache"])
    assert result.exit_code == 0, result.output
    assert "phase first: done" in result.output  # not trained again
    assert (out / "phases/first/last.safetensors").stat().st_mtime_ns == stamp
    assert (out / "ship/tiny.v1.safetensors").is_file()
    # the second phase started from the first's weights, by path and hash
    init = read_metadata(out / "phases/second/last.safetensors")["extra"]["init"]
    assert init["name"].endswith("phases/first/last.safetensors")
    # the machine's settings reached the phases; the recipe never held them
    saved = yaml.safe_load((out / "phases/second/config.yaml").read_text())
    assert saved["threads"] == 2 and saved["cache"] is True and saved["device"] == "auto"
    assert yaml.safe_load((out / "phases/first/config.yaml").read_text())["threads"] == 1
    # a folder made by another recipe is refused, naming both
    other = tmp_path / "other.yaml"
    other.write_text(recipe_path.read_text().replace("name: tiny\n", "name: other\n", 1))
    result = runner.invoke(cli, ["reproduce", str(other), "--output", str(out)])
    assert result.exit_code == 1 and "'tiny'" in result.output and "'other'" in result.output


@pytest.mark.parametrize(("changes", "message"), [
    ({"colour": 1}, "recipe: unknown key"),
    ({"phases": [{"name": "first", "set": {"epochs": 1, "nope": 2}}]},
     "phase first: unknown config key.*nope"),
    ({"phases": [{"name": "first", "init": "rdpd-light"}]},
     "phase first: init 'rdpd-light' cannot be resolved.*alias"),
    ({"phases": [{"name": "first", "init": "previous"}]}, "first phase"),
    ({"phases": [{"name": "first", "set": {"synthetic_data": "nothing"}}]},
     "phase first: .*no data step|not found"),
    ({"data": [{"name": "synth", "synth": {"input": "scenes"}}]},
     "data step synth: input 'scenes' is no earlier data step"),
    ({"data": [{"name": "s", "scenes": {"sequences": 1, "width": -3}}]}, "data step s: width"),
    ({"data": [{"name": "s", "scenes": {"sequences": 1, "seed": -1}}]}, "data step s: seed"),
    ({"data": [{"name": "s", "scenes": {"sequences": 1.5}}]}, "data step s: sequences"),
    ({"data": [{"name": "s", "scenes": {"sequences": 1}},
               {"name": "y", "synth": {"input": "s", "seed": 2.5}}]}, "data step y: seed"),
    ({"ship": {"tag": "x.v1", "phase": "third"}}, "ship: .*no phase 'third'"),
    ({"ship": {"name": "x"}}, "ship: .name. is now .tag."),
    ({"ship": {"tag": "Tiny"}}, "ship: tag .* is not ARCHITECTURE.vN"),
    ({"ship": {"tag": "../x.v1"}}, "ship: .*plain name"),
    ({"ship": {"tag": "x.v1", "output": {"flips": "yes"}}}, "ship output flips: .yes. is not"),
    ({"train": {"architecture": "rdpd-huge", "synthetic_data": "synth"}},
     "architecture must be one of rdpd-light"),
    ({"train": {"architecture": "rdpd-light", "width": 1.0, "synthetic_data": "synth"}},
     "architecture rdpd-light sets width; give one or the other"),
    ({"phases": [{"name": "first", "set": {"workers": 12}}]},
     "phase first: workers: machine settings are not part of a model's recipe.*--loader-workers"),
    ({"train": {"model": "rdpd", "synthetic_data": "synth", "frame_store": "runs/x"}},
     "train: frame_store: machine settings .*--frame-store"),
    ({"evaluate": [{"name": "raw", "dataset": "synth", "encoding": "linear",
                    "white_level": 255}]}, "evaluate raw: linear views need black_level"),
    ({"evaluate": [{"name": "raw", "dataset": "synth", "gain": 2}]},
     "evaluate entry 1: expected .name, dataset, split. and, for raw views"),
])
def test_bad_recipes_are_refused_before_any_work(tmp_path, changes, message):
    path = _tiny_recipe(tmp_path, **changes)
    result = CliRunner().invoke(cli, ["reproduce", str(path), "--output", str(tmp_path / "run"),
                                      "--dry-run"])
    assert result.exit_code in (1, 2), result.output
    assert "Traceback" not in result.output
    assert str(path) in result.output or "tiny.yaml" in result.output
    assert re.search(message, result.output), result.output
    assert not (tmp_path / "run").exists()


def test_architecture_by_its_registry_name_stands_for_its_keys(tmp_path):
    from dualpixel.training.recipe import phase_config

    path = _tiny_recipe(tmp_path, train={
        "architecture": "rdpd-light", "synthetic_data": "synth", "val_data": "synth",
        "val_split": "train", **{k: v for k, v in TINY_PHASE.items() if k != "width"}})
    recipe = load_recipe(path)
    first = phase_config(recipe, 0, tmp_path / "run", None)
    assert (first.model, first.width, first.residual, first.refiner) == (
        "rdpd", 0.5, True, [32, 64, 128])
    assert phase_config(recipe, 1, tmp_path / "run", "w").refiner == [4, 8]  # the phase's own


def test_a_recipe_with_the_old_name_of_lens_sets_is_read_with_a_warning(tmp_path):
    from dualpixel.training.recipe import synth_config

    path = _tiny_recipe(tmp_path, data=[
        {"name": "scenes", "scenes": {**TINY_SCENES, "seed": 1}},
        {"name": "synth", "synth": {"input": "scenes", "cameras": ["set1", "set3"]}}])
    recipe = load_recipe(path)
    with pytest.warns(FutureWarning, match=r"data step synth: cameras is now lens_sets"):
        config, _, _ = synth_config(recipe, recipe.data[1], tmp_path / "run")
    assert config.lens_sets == ("set1", "set3")


def test_missing_recipe_is_named(tmp_path):
    with pytest.raises(InputFileError, match="recipe not found"):
        load_recipe(tmp_path / "none.yaml")


def test_a_recipe_extends_another_by_name(tmp_path):
    base = _tiny_recipe(tmp_path)
    child = tmp_path / "child.yaml"
    child.write_text(yaml.safe_dump({
        "name": "child", "extends": base.name,
        "data": [{"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set2"],
                                             "max_layers": 40, "noise_sigmas": [0.01]}}],
        "train": {"learning_rate": 5e-4},
        "phases": [{"name": "second", "set": {"epochs": 2}}, {"name": "third"}],
        "ship": {"tag": "child.v1"}}, sort_keys=False))
    parent, recipe = load_recipe(base), load_recipe(child)
    assert [s.name for s in recipe.data] == ["scenes", "synth"]  # replaced in place
    assert recipe.data[1].args["lens_sets"] == ["set2"] and recipe.data[0] == parent.data[0]
    assert recipe.train == {**parent.train, "learning_rate": 5e-4}
    assert [p.name for p in recipe.phases] == ["first", "second", "third"]
    assert recipe.phases[1].settings == {"epochs": 2} and recipe.phases[0] == parent.phases[0]
    assert recipe.evaluate == parent.evaluate and recipe.shipped_tag == "child.v1"
    loop = tmp_path / "loop.yaml"
    loop.write_text("name: loop\nextends: loop.yaml\nphases: [{name: a}]\n")
    with pytest.raises(InputFileError, match=r"extends: loop\.yaml makes a cycle"):
        load_recipe(loop)
    missing = tmp_path / "missing.yaml"
    missing.write_text("name: m\nextends: nowhere.yaml\nphases: [{name: a}]\n")
    with pytest.raises(InputFileError, match=r"extends: nowhere\.yaml is no recipe"):
        load_recipe(missing)
    missing.write_text(f"name: m\nextends: {base}\nphases: [{{name: a}}]\n")
    with pytest.raises(InputFileError, match="relative to this recipe's folder"):
        load_recipe(missing)  # an absolute path would not travel with the repository


def test_a_variant_drops_a_phase_and_a_step_of_its_base(tmp_path):
    """``{name: NAME, drop: true}`` leaves the base's phase or data step out; the plan marks a
    step that no phase or evaluation reads, which ``reproduce`` does not make."""
    base = _tiny_recipe(tmp_path, data=[
        {"name": "scenes", "scenes": {**TINY_SCENES, "seed": 1}},
        {"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set1"], "max_layers": 40,
                                    "noise_sigmas": [0.01]}},
        {"name": "spare", "synth": {"input": "scenes", "lens_sets": ["set2"], "max_layers": 40,
                                    "noise_sigmas": [0.01]}}])
    child = tmp_path / "child.yaml"
    child.write_text(yaml.safe_dump({
        "name": "child", "extends": base.name, "phases": [{"name": "second", "drop": True}],
        "ship": {"tag": "child.v1"}}, sort_keys=False))
    recipe = load_recipe(child)
    assert [p.name for p in recipe.phases] == ["first"] and recipe.shipped_phase == "first"
    assert [s.name for s in recipe.data] == ["scenes", "synth", "spare"]
    plan = CliRunner().invoke(cli, ["reproduce", str(child), "-o", str(tmp_path / "run"),
                                    "--dry-run"])
    assert plan.exit_code == 0, plan.output
    assert re.search(r"spare .*\[not read: not made\]", plan.output)
    assert not re.search(r"synth .*\[not read", plan.output)
    child.write_text(yaml.safe_dump({
        "name": "child", "extends": base.name, "data": [{"name": "spare", "drop": True}]}))
    assert [s.name for s in load_recipe(child).data] == ["scenes", "synth"]
    for entry, problem in [({"name": "third", "drop": True}, "base recipe has no phases entry"),
                           ({"name": "first", "drop": True, "set": {}}, "and nothing else"),
                           ({"name": "first", "drop": False}, "and nothing else")]:
        child.write_text(yaml.safe_dump({"name": "child", "extends": base.name,
                                         "phases": [entry]}))
        with pytest.raises(InputFileError, match=f"phases entry {entry['name']}: .*{problem}"):
            load_recipe(child)
    alone = tmp_path / "alone.yaml"
    alone.write_text(yaml.safe_dump({"name": "alone", "phases": [{"name": "a", "drop": True}]}))
    with pytest.raises(InputFileError, match=r"unknown key.*drop"):
        load_recipe(alone)  # nothing to drop from without a base


def test_a_variant_extends_a_recipe_of_another_folder(tmp_path):
    """An experiment under ``experiments/recipes`` names only what changes from a recipe of
    ``recipes/`` (a relative path); the result is the base with those keys replaced."""
    base = _tiny_recipe(tmp_path / "recipes")
    variant = tmp_path / "experiments" / "recipes" / "seed.yaml"
    variant.parent.mkdir(parents=True)
    variant.write_text(yaml.safe_dump({
        "name": "seed", "extends": f"../../recipes/{base.name}", "train": {"seed": 7},
        "ship": {"tag": "seed.v1"}}, sort_keys=False))
    parent, recipe = load_recipe(base), load_recipe(variant)
    assert recipe.name == "seed" and recipe.shipped_tag == "seed.v1"
    assert recipe.data == parent.data and recipe.phases == parent.phases
    assert recipe.train == {**parent.train, "seed": 7}


def test_an_evaluation_of_raw_views_reaches_eval_with_their_encoding(tmp_path, monkeypatch):
    """``encoding: linear`` with the levels: the shipped weights see the views as
    ``dualpixel eval --encoding linear`` feeds them."""
    from dualpixel.evaluation import run
    from dualpixel.training import recipe as recipes

    path = _tiny_recipe(tmp_path, evaluate=[
        {"name": "raw", "dataset": "synth", "encoding": "linear", "black_level": 16,
         "white_level": 255},
        {"name": "display", "dataset": "synth"}])
    recipe = load_recipe(path)
    (tmp_path / "run" / "data" / "synth").mkdir(parents=True)
    seen = {}

    def fake_evaluation(request, deblurrer, method):  # what the evaluation was asked
        seen[request.output.name] = request.encoding
        request.output.mkdir(parents=True)
        (request.output / "summary.json").write_text(
            '{"summary": {"model": {"combined": {"psnr": 30.0, "ssim": 0.9}}}}')

    monkeypatch.setattr(run, "run_evaluation", fake_evaluation)
    monkeypatch.setattr(recipes, "_data_folder",
                        lambda recipe, output, name: output / "data" / name)
    monkeypatch.setattr("dualpixel.inference.pipeline.build_deblurrer",
                        lambda weights, **settings: None)
    recipes.evaluate_shipped(recipe, tmp_path / "w.safetensors", tmp_path / "run",
                             log=lambda line: None)
    assert seen["raw"].linear and (seen["raw"].black_level, seen["raw"].white_level) == (16, 255)
    assert not seen["display"].linear


def test_a_start_tag_that_no_longer_ships_comes_from_a_file_given_for_it(tmp_path):
    """A phase's ``init: TAG`` whose weights left the package names the recipe that remakes
    them and takes a file for the tag (``--tag-file TAG=PATH``); the phase then starts from
    that file, and the run says whether it is the released one."""
    runner = CliRunner()
    start_run = tmp_path / "start"
    result = runner.invoke(cli, ["reproduce", str(_tiny_recipe(tmp_path / "a")), "--output",
                                 str(start_run), "--until", "first", "--no-progress",
                                 *MACHINE_OPTIONS])
    assert result.exit_code == 0, result.output
    weights = start_run / "phases/first/last.safetensors"
    retired = _tiny_recipe(tmp_path / "b", phases=[{"name": "first", "init": "rdpd-wide.v2"}])
    out = tmp_path / "run"
    refused = runner.invoke(cli, ["reproduce", str(retired), "--output", str(out), "--dry-run"])
    assert refused.exit_code == 1 and "Traceback" not in refused.output
    assert "rdpd-wide.v2 no longer ships" in refused.output
    assert "recipes/rdpd-wide.yaml --output DIR --until canon-both" in refused.output
    assert "DIR/phases/canon-both/last.safetensors" in refused.output
    assert "--tag-file rdpd-wide.v2=PATH" in refused.output
    given = ["--tag-file", f"rdpd-wide.v2={weights}"]
    result = runner.invoke(cli, ["reproduce", str(retired), "--output", str(out), *given,
                                 "--no-progress", *MACHINE_OPTIONS])
    assert result.exit_code == 0, result.output
    assert f"rdpd-wide.v2: {weights} is not the released file" in result.output
    init = read_metadata(out / "phases/first/last.safetensors")["extra"]["init"]
    assert init["name"] == str(weights)
    for options, message in [
        (["--tag-file", f"rdpd-light.v16={weights}"], "starts from no tag 'rdpd-light.v16'"),
        (["--tag-file", f"rdpd-wide.v2={tmp_path / 'none.safetensors'}"],
         "none.safetensors: weights for rdpd-wide.v2 not found"),
        (["--tag-file", "rdpd-wide.v2"], "expected TAG=PATH"),
    ]:
        bad = runner.invoke(cli, ["reproduce", str(retired), "--output", str(tmp_path / "x"),
                                  "--dry-run", *options])
        assert bad.exit_code in (1, 2) and "Traceback" not in bad.output, bad.output
        assert message in bad.output, bad.output
        assert not (tmp_path / "x").exists()
    # a phase run --from without its predecessor starts from the tag that predecessor made:
    # one that no longer ships is refused the same way and comes from a file given for it
    phases = [{"name": "first"}, {"name": "canon-both"}, {"name": "after", "init": "previous"}]
    wide = _tiny_recipe(tmp_path / "c", phases=phases).rename(tmp_path / "c/rdpd-wide.yaml")
    late = ["reproduce", str(wide), "--output", str(tmp_path / "late"), "--from", "after"]
    refused = runner.invoke(cli, [*late, "--dry-run"])
    assert refused.exit_code in (1, 2) and "Traceback" not in refused.output, refused.output
    assert "rdpd-wide.v2 no longer ships" in refused.output, refused.output
    assert "--tag-file rdpd-wide.v2=PATH" in refused.output
    result = runner.invoke(cli, [*late, *given, "--no-progress", *MACHINE_OPTIONS])
    assert result.exit_code == 0, result.output
    init = read_metadata(tmp_path / "late/phases/after/last.safetensors")["extra"]["init"]
    assert init["name"] == str(weights)


def test_a_copy_of_a_shipped_start_is_named_the_released_file(tmp_path):
    from dualpixel.weights import WEIGHTS

    copy = tmp_path / "copy.safetensors"
    shutil.copyfile(WEIGHTS["rdpd-light.v16"].path, copy)
    path = _tiny_recipe(tmp_path, phases=[{"name": "first", "init": "rdpd-light.v16"}])
    result = CliRunner().invoke(cli, ["reproduce", str(path), "--output", str(tmp_path / "run"),
                                      "--dry-run", "--tag-file", f"rdpd-light.v16={copy}"])
    assert result.exit_code == 0, result.output
    assert f"rdpd-light.v16: {copy}, the released file" in result.output
    assert load_recipe(path, tag_files={"rdpd-light.v16": copy}).tag_files == {
        "rdpd-light.v16": str(copy)}
