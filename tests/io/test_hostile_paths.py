"""Names that become paths stay plain, and nothing is written through a planted link (#55)."""

import os
import time

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, OutputFileError, ParameterError
from dualpixel.io.atomic import open_for_append
from dualpixel.io.dpdd import role_folder
from dualpixel.io.lock import LOCK_NAME, folder_lock
from dualpixel.training.recipe import load_recipe

RECIPE = """
name: tiny
data:
  - name: {step}
    scenes: {{sequences: 1, frames: 1, width: 64, height: 48, layout: photo, seed: 1}}
phases:
  - name: {phase}
ship: {{tag: {ship}}}
evaluate:
  - {{name: {evaluate}, dataset: {step}, split: test}}
"""


@pytest.mark.parametrize("field", ["step", "phase", "ship", "evaluate"])
@pytest.mark.parametrize("bad", ["../../x", "/tmp/abs", "..", "a/b"])
def test_recipe_names_that_would_leave_the_run_folder_are_refused(tmp_path, field, bad):
    names = {"step": "scenes", "phase": "one", "ship": "model.v1", "evaluate": "held-out"}
    names[field] = f"'{bad}'"
    path = tmp_path / "recipe.yaml"
    path.write_text(RECIPE.format(**names))
    with pytest.raises(InputFileError, match="plain name"):
        load_recipe(path)


def test_split_names_stay_plain(tmp_path):
    assert role_folder(tmp_path, "test", "left") == tmp_path / "test_l" / "source"
    for bad in ("../x", "/abs", ".."):
        with pytest.raises(ParameterError, match="split"):
            role_folder(tmp_path, bad, "left")
    result = CliRunner().invoke(cli, ["deblur", "--input", str(tmp_path), "--split", "../x",
                                      "-o", str(tmp_path / "out")])
    assert result.exit_code != 0 and "split" in result.output
    assert "Traceback" not in result.output


def test_the_lock_is_never_taken_through_a_link(tmp_path):
    precious = tmp_path / "precious.txt"
    precious.write_text("keep me")
    folder = tmp_path / "out"
    folder.mkdir()
    os.symlink(precious, folder / LOCK_NAME)
    with pytest.raises(OutputFileError, match="symbolic link"):
        with folder_lock(folder, "test"):
            pass
    assert precious.read_text() == "keep me"
    (folder / LOCK_NAME).unlink()
    with folder_lock(folder, "test") as lock:  # a plain lock file still works
        assert "pid" in lock.read_text()


def test_appending_never_writes_through_a_link(tmp_path):
    precious = tmp_path / "precious.txt"
    precious.write_text("keep me")
    os.symlink(precious, tmp_path / "manifest.jsonl")
    with pytest.raises(OutputFileError, match="symbolic link"):
        open_for_append(tmp_path / "manifest.jsonl")
    assert precious.read_text() == "keep me"
    with open_for_append(tmp_path / "fresh.jsonl") as handle:
        handle.write("line\n")
    assert (tmp_path / "fresh.jsonl").read_text() == "line\n"


def test_documents_are_bounded_in_depth_and_alias_expansion(tmp_path):
    from dualpixel.io.documents import read_mapping

    bomb = ["a: &a ['x', 'x', 'x', 'x', 'x', 'x', 'x', 'x', 'x', 'x']"]
    for level in range(1, 9):
        previous = chr(ord("a") + level - 1)
        name = chr(ord("a") + level)
        bomb.append(f"{name}: &{name} [{', '.join(['*' + previous] * 10)}]")
    (tmp_path / "bomb.yaml").write_text("\n".join(bomb) + "\n")
    with pytest.raises(InputFileError, match="aliases are expanded"):
        read_mapping(tmp_path / "bomb.yaml", "recipe", syntax="yaml")
    (tmp_path / "deep.json").write_text('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(InputFileError, match="nested"):
        read_mapping(tmp_path / "deep.json", "camera file")
    (tmp_path / "deep.yaml").write_text("a: " + "[" * 100 + "]" * 100 + "\n")
    with pytest.raises(InputFileError, match="nested more than"):
        read_mapping(tmp_path / "deep.yaml", "config", syntax="yaml")
    (tmp_path / "ok.yaml").write_text("a: &x [1, 2]\nb: *x\n")
    assert read_mapping(tmp_path / "ok.yaml", "config", syntax="yaml") == {"a": [1, 2],
                                                                            "b": [1, 2]}


def test_truncated_images_are_refused(tmp_path):
    import cv2
    import numpy as np

    from dualpixel.io.images import read_rgb

    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (64, 80, 3), dtype=np.uint8)
    for suffix in (".png", ".jpg"):
        whole = tmp_path / f"whole{suffix}"
        cv2.imwrite(str(whole), image)
        assert read_rgb(whole).shape == (64, 80, 3)
        cut = tmp_path / f"cut{suffix}"
        cut.write_bytes(whole.read_bytes()[: int(whole.stat().st_size * 0.6)])
        with pytest.raises(InputFileError, match="truncated"):
            read_rgb(cut)


def test_tiles_too_small_for_the_network_warn(refined_model):
    from dualpixel.inference import Deblurrer

    with pytest.warns(UserWarning, match="too little context"):
        Deblurrer(refined_model, tile=64)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Deblurrer(refined_model, tile=256)


@pytest.fixture()
def inputs(tmp_path, tiny_checkpoint):
    """Views, a combined image, a DPDD folder, an RGB-D pair and a checkpoint, with their bytes."""
    import numpy as np

    from dualpixel.io.images import write_png

    rng = np.random.default_rng(0)
    image = rng.random((48, 64, 3)).astype(np.float32)
    for name in ("left.png", "right.png", "combined.png", "scene/rgb.png",
                 "dpdd/test_l/source/a.png", "dpdd/test_r/source/a.png",
                 "dpdd/test_c/source/a.png", "dpdd/test_c/target/a.png"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        write_png(tmp_path / name, image)
    np.save(tmp_path / "scene" / "depth.npy", np.full((48, 64), 2.0, np.float32))
    checkpoint = tmp_path / "model.safetensors"
    checkpoint.write_bytes(tiny_checkpoint.read_bytes())
    (tmp_path / "link.png").symlink_to(tmp_path / "left.png")
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    return tmp_path, before


@pytest.mark.parametrize("args, says", [
    (["deblur", "--left", "{d}/left.png", "--right", "{d}/right.png", "--combined",
      "{d}/combined.png", "-o", "{d}/combined.png"], "is the input --combined"),
    (["deblur", "--left", "{d}/left.png", "--right", "{d}/right.png", "-o", "{d}/link.png"],
     "is the input --left"),
    (["deblur", "--input", "{d}/dpdd", "-o", "{d}/dpdd/test_c/target"],
     "lies inside the input folder --input"),
    (["export", "--checkpoint", "{d}/model.safetensors", "-o", "{d}/model.safetensors"],
     "is the input --checkpoint"),
    (["demo", "--rgb", "{d}/scene/rgb.png", "--depth", "{d}/scene/depth.npy", "-o",
      "{d}/scene"], "holds the input --rgb"),
    (["stats", "{d}/dpdd", "--json", "{d}/dpdd/stats.json"], "inside the input folder DATASETS"),
    (["synth", "--input", "{d}/dpdd", "--output", "{d}/scene", "--camera",
      "{d}/scene/depth.npy"], "holds the input --camera"),
    (["niqe", "fit", "--images", "{d}/scene", "-o", "{d}/scene/model.npz"],
     "inside the input folder --input"),
])
def test_an_output_that_is_or_holds_an_input_is_refused_before_any_work(inputs, args, says):
    folder, before = inputs
    result = CliRunner().invoke(cli, [a.format(d=folder) for a in args])
    assert result.exit_code == 1, result.output
    assert says in result.output and "inputs are never outputs" in result.output
    assert "Traceback" not in result.output
    after = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert after == before  # nothing written, nothing replaced


def test_outputs_apart_in_the_library(tmp_path):
    from dualpixel.io.paths import check_outputs_apart

    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "a.png").write_bytes(b"x")
    check_outputs_apart({"--input": [tmp_path / "in"]}, {"--output": tmp_path / "out"})
    check_outputs_apart({"--input": [tmp_path / "missing"]}, {"--output": tmp_path / "missing"})
    with pytest.raises(OutputFileError, match="holds the input --input"):
        check_outputs_apart({"--input": [tmp_path / "in" / "a.png"]}, {"-o": tmp_path})


def test_an_interrupted_scenes_folder_is_not_taken_as_finished(tmp_path, monkeypatch):
    import json

    from dualpixel.synthesis import scenes

    config = scenes.SceneConfig(width=64, height=48, frames=1, layout="photo")
    write = scenes._write_sequence

    def killed_at_the_second(folder, k, *args):
        if k == 1:
            raise KeyboardInterrupt
        write(folder, k, *args)

    monkeypatch.setattr(scenes, "_write_sequence", killed_at_the_second)
    with pytest.raises(KeyboardInterrupt):
        scenes.write_scene_folder(tmp_path / "scenes", 2, config, progress=False)
    monkeypatch.undo()
    description = json.loads((tmp_path / "scenes" / scenes.SCENES_DESCRIPTION).read_text())
    assert description["status"] == "incomplete"
    result = CliRunner().invoke(cli, ["synth", "--input", str(tmp_path / "scenes"), "-o",
                                      str(tmp_path / "dataset")])
    assert result.exit_code == 1 and "unfinished" in result.output, result.output
    assert not (tmp_path / "dataset").exists()
    scenes.write_scene_folder(tmp_path / "scenes", 2, config, progress=False)  # the rerun ends it
    description = json.loads((tmp_path / "scenes" / scenes.SCENES_DESCRIPTION).read_text())
    assert description["status"] == "complete" and description["sequences"] == 2


@pytest.mark.parametrize("key, value", [
    ("iterations_per_epoch", "1e12"), ("iterations_per_epoch", "1000000000000"),
    ("patch_size", "100000"), ("epochs", "0"), ("seed", "-1"), ("seed", str(2**70)),
    ("seed", "1.5"), ("seed", "10**23"), ("workers", "100000"),
])
def test_values_that_size_work_are_bounded_before_any(tmp_path, key, value):
    from dualpixel.training import load_config

    overrides = {"synthetic_data": str(tmp_path), key: value}
    with pytest.raises(ParameterError, match=key):
        load_config(None, overrides)
    result = CliRunner().invoke(cli, ["train", "--set", f"synthetic_data={tmp_path}", "--set",
                                      f"{key}={value}", "-o", str(tmp_path / "run")])
    assert result.exit_code == 2 and key in result.output and "Traceback" not in result.output
    assert not (tmp_path / "run").exists()


def test_the_api_refuses_what_is_not_a_model_or_an_image(tiny_checkpoint):
    import numpy as np
    import torch

    import dualpixel

    view = np.full((32, 48, 3), 0.5, np.float32)
    with pytest.raises(ParameterError, match="load_model takes"):
        dualpixel.load_model(5)
    with pytest.raises(ParameterError, match="model must be"):
        dualpixel.deblur(view, view, model=object())
    with pytest.raises(ParameterError, match="meta tensor"):
        dualpixel.deblur(torch.zeros(3, 32, 48, device="meta"), torch.zeros(3, 32, 48))
    with pytest.raises(ParameterError, match=r"\[0, 1\]"):
        dualpixel.deblur(np.full_like(view, 1.4), view, model=tiny_checkpoint)
    # half-precision tensors are images too: read exactly, answered as float32
    half = torch.full((3, 32, 48), 0.5, dtype=torch.bfloat16)
    out = dualpixel.deblur(half, half, model=tiny_checkpoint, device="cpu")
    assert out.dtype == torch.float32 and out.shape == (3, 32, 48)


@pytest.mark.parametrize("compare, says", [
    (["input={d}"], "name of the input's row"),
    (["model={d}"], "name of the model's row"),
    (["../x={d}"], "plain name"),
    (["a={d}", "a={d}"], "given twice"),
])
def test_eval_compare_names_stay_apart_from_the_rows(tmp_path, compare, says):
    for name in ("pred", "target"):
        (tmp_path / name).mkdir()
    args = ["eval", "--pred", str(tmp_path / "pred"), "--target", str(tmp_path / "target"),
            "-o", str(tmp_path / "report")]
    for item in compare:
        args += ["--compare", item.format(d=tmp_path)]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2 and says in result.output, result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("marker", ["[1, 2]", "[" * 100_000, "\xff\xfe binary"])
def test_a_run_folder_with_a_hostile_recipe_record_is_refused(tmp_path, marker):
    recipe = tmp_path / "recipe.yaml"
    recipe.write_text(RECIPE.format(step="scenes", phase="one", ship="model.v1",
                                    evaluate="held-out")
                      + "train: {model: rdpd, width: 0.125, synthetic_data: scenes}\n")
    run = tmp_path / "run"
    run.mkdir()
    (run / "recipe.json").write_bytes(marker.encode("utf-8", "surrogateescape")
                                      if marker.isascii() else marker.encode("latin-1"))
    result = CliRunner().invoke(cli, ["reproduce", str(recipe), "--output", str(run)])
    assert result.exit_code == 1 and "recipe.json" in result.output, result.output
    assert "Traceback" not in result.output and not (run / "data").exists()


def test_array_files_declaring_too_much_are_refused_before_loading(tmp_path):
    import io
    import zipfile

    import numpy as np

    from dualpixel.evaluation.niqe import NIQEModel
    from dualpixel.io.images import load_npy

    header = io.BytesIO()  # a header declaring 4 GiB of float64, and no data
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (1 << 29,)})
    with zipfile.ZipFile(tmp_path / "niqe.npz", "w") as archive:
        archive.writestr("mean.npy", header.getvalue())
    with pytest.raises(InputFileError,
                       match=r"declares arrays of 4 GiB; a file of this kind holds at most 1 MiB"):
        NIQEModel.load(tmp_path / "niqe.npz")
    (tmp_path / "depth.npy").write_bytes(
        header.getvalue().replace(b"(536870912,)", b"(10000000000,)"))
    with pytest.raises(InputFileError,
                       match=r"declares arrays of 74\.5 GiB, more than the .* memory available"):
        load_npy(tmp_path / "depth.npy")


def test_a_checkpoint_whose_metadata_asks_for_a_huge_network_is_refused(tmp_path,
                                                                       tiny_checkpoint):
    import json

    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    import dualpixel

    with safe_open(str(tiny_checkpoint), framework="pt") as handle:
        metadata = dict(handle.metadata())
    metadata["refiner"] = json.dumps([60000, 60000])
    save_file(load_file(str(tiny_checkpoint)), str(tmp_path / "huge.safetensors"), metadata)
    with pytest.raises(InputFileError, match="asks for a network no checkpoint holds"):
        dualpixel.load_model(tmp_path / "huge.safetensors")


def test_long_output_names_are_judged_by_their_own_length(tmp_path):
    from dualpixel.io.atomic import atomic_path, check_writable

    longest = tmp_path / ("x" * 250 + ".png")  # fits; its temporary name must too
    with atomic_path(longest) as tmp:
        tmp.write_bytes(b"data")
    assert longest.read_bytes() == b"data"
    with pytest.raises(OutputFileError, match="bytes long") as caught:
        check_writable(tmp_path / ("y" * 300 + ".png"))
    assert "y" * 300 in str(caught.value)  # the name asked for, not a temporary one


@pytest.mark.parametrize("dtype", ["int16", "float64"])
def test_views_of_signed_or_float_samples_are_refused_by_name(tmp_path, dtype):
    import numpy as np
    import tifffile

    view, other = tmp_path / "view.tif", tmp_path / "other.tif"
    for path in (view, other):
        tifffile.imwrite(path, (np.random.default_rng(0).random((48, 64, 3)) * 100).astype(dtype))
    result = CliRunner().invoke(cli, ["deblur", "--left", str(view), "--right", str(other), "-o",
                                      str(tmp_path / "out.png")])
    assert result.exit_code == 1 and f"holds {dtype} samples" in result.output, result.output
    assert "Traceback" not in result.output


def test_a_set_value_yaml_cannot_read_is_a_usage_error(tmp_path):
    result = CliRunner().invoke(cli, ["train", "--set", f"synthetic_data={tmp_path}", "--set",
                                      "epochs=[", "-o", str(tmp_path / "run")])
    assert result.exit_code == 2 and "epochs: '[' is not a value" in result.output
    assert "Traceback" not in result.output


def test_a_killed_write_leaves_nothing_once_the_file_is_written_again(tmp_path):
    from dualpixel.io.atomic import LEFTOVER_AGE, PARTIAL_MARKER, atomic_path

    leftover = tmp_path / f".model{PARTIAL_MARKER}k1ll3d00.onnx"  # as a killed export leaves it
    leftover.write_bytes(b"half a graph")
    other = tmp_path / f".other{PARTIAL_MARKER}k1ll3d00.onnx"  # another file's: not ours
    other.write_bytes(b"x")
    for path in (leftover, other):  # written before the kill, over an hour ago
        os.utime(path, (time.time() - LEFTOVER_AGE - 5, time.time() - LEFTOVER_AGE - 5))
    with atomic_path(tmp_path / "model.onnx") as tmp:
        tmp.write_bytes(b"graph")
    assert not leftover.exists() and other.exists()
    assert (tmp_path / "model.onnx").read_bytes() == b"graph"


def _write_often(args):
    from dualpixel.io.atomic import atomic_path

    path, seed = args
    data = np.random.default_rng(seed).integers(0, 255, 300_000, dtype=np.uint8)
    try:
        for _ in range(40):
            with atomic_path(path) as tmp:
                np.save(tmp, data)
    except Exception as error:  # reported as text: the parent must hear of it
        return f"{type(error).__name__}: {error}"
    return None


def test_processes_writing_one_file_at_once_keep_each_others_temporary_files(tmp_path):
    """Loader workers fill the frame store side by side and may write the same entry at once:
    a live writer's temporary file is no leftover to the others."""
    import multiprocessing

    from dualpixel.io.atomic import LEFTOVER_AGE, PARTIAL_MARKER, atomic_path

    path = tmp_path / "entry.npy"
    with multiprocessing.get_context("spawn").Pool(4) as pool:
        failures = [f for f in pool.map(_write_often, [(path, k) for k in range(4)]) if f]
    assert not failures, failures
    assert np.load(path).shape == (300_000,)
    assert not list(tmp_path.glob(f".*{PARTIAL_MARKER}*"))
    # another writer's temporary file stays while it may be live (touched within the hour,
    # as an export that computes for minutes before it writes); untouched longer, it goes
    held = tmp_path / f".entry{PARTIAL_MARKER}h0ld1ng0.npy"
    held.write_bytes(b"being written")
    os.utime(held, (time.time() - 600, time.time() - 600))
    with atomic_path(path) as tmp:
        np.save(tmp, np.zeros(3))
    assert held.exists()
    os.utime(held, (time.time() - LEFTOVER_AGE - 1, time.time() - LEFTOVER_AGE - 1))
    with atomic_path(path) as tmp:
        np.save(tmp, np.zeros(3))
    assert not held.exists()


def test_a_killed_writers_file_goes_at_the_rerun_however_recent(tmp_path):
    """A temporary file names its writer's process: once that process is gone (killed), the
    next write of the same file removes it at once, without waiting for it to age; a live
    writer's stays."""
    import subprocess
    import sys
    from pathlib import Path

    from dualpixel.io.atomic import PARTIAL_MARKER, atomic_path

    code = ("import os, sys, time\nfrom dualpixel.io.atomic import atomic_path\n"
            "with atomic_path(sys.argv[1]) as tmp:\n"
            "    tmp.write_bytes(b'half')\n    print(tmp, flush=True)\n    time.sleep(60)\n")
    writer = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "out.png")],
                              stdout=subprocess.PIPE, text=True)
    partial = Path(writer.stdout.readline().strip())
    assert partial.is_file() and PARTIAL_MARKER in partial.name and f"p{writer.pid}-" in \
        partial.name
    with atomic_path(tmp_path / "out.png") as tmp:  # the writer lives: its file stays
        tmp.write_bytes(b"mine")
    assert partial.is_file()
    writer.kill()
    writer.wait()
    with atomic_path(tmp_path / "out.png") as tmp:  # killed seconds ago: removed
        tmp.write_bytes(b"again")
    assert not partial.exists() and (tmp_path / "out.png").read_bytes() == b"again"
    assert not list(tmp_path.glob(f".*{PARTIAL_MARKER}*"))


def _write_pair(folder, size=(64, 96)):
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for name in ("left.png", "right.png", "target.png"):
        cv2.imwrite(str(folder / name), rng.integers(0, 255, (*size, 3), dtype=np.uint8))


@pytest.mark.parametrize("kind", ["loop", "dangling"])
def test_links_that_lead_nowhere_are_named_as_such(tmp_path, kind):
    """Issue #72: a view that is a looping or dangling link is said to be one, by name, in an
    option and inside a folder of pairs (not "missing", not "does not exist")."""
    scene = tmp_path / "pairs" / "a"
    _write_pair(scene)
    (scene / "right.png").unlink()
    if kind == "loop":
        os.symlink(scene / "back", scene / "right.png")
        os.symlink(scene / "right.png", scene / "back")
        said = "right.png: is a symbolic link that loops"
    else:
        os.symlink(scene / "gone.png", scene / "right.png")
        said = "right.png: is a symbolic link to "
    runner = CliRunner()
    option = runner.invoke(cli, ["deblur", "--left", str(scene / "left.png"), "--right",
                                 str(scene / "right.png"), "-o", str(tmp_path / "out.png")])
    assert option.exit_code == 2 and said in option.output, option.output
    folder = runner.invoke(cli, ["check-model", "--input", str(tmp_path / "pairs"), "-o",
                                 str(tmp_path / "report")])
    assert folder.exit_code == 1 and said in folder.output, folder.output
    for result in (option, folder):
        assert "Traceback" not in result.output


def test_images_too_small_for_a_metric_or_a_check_name_the_file(tmp_path):
    """Issue #72: 6x6 images are refused by NIQE, SSIM and the target-free checks, each naming
    the file it could not score."""
    scene = tmp_path / "scenes" / "tiny"
    _write_pair(scene, size=(6, 6))
    runner = CliRunner()
    niqe = runner.invoke(cli, ["eval", "--dataset", str(tmp_path / "scenes"), "-o",
                               str(tmp_path / "e1")])
    assert niqe.exit_code == 1 and "left.png: NIQE needs images of at least" in niqe.output
    ssim = runner.invoke(cli, ["eval", "--dataset", str(tmp_path / "scenes"), "-o",
                               str(tmp_path / "e2"), "--no-niqe"])
    assert ssim.exit_code == 1 and "left.png: SSIM needs images of at least" in ssim.output
    check = runner.invoke(cli, ["check-model", "--input", str(tmp_path / "scenes"), "-o",
                                str(tmp_path / "c")])
    assert check.exit_code == 1, check.output
    assert "left.png: images must be at least 128x64 px for the target-free checks" in \
        check.output


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_a_folder_that_takes_no_file_is_named_before_any_work(tmp_path):
    """The access bits pass for root, and /proc takes no new file: the output is checked by
    making a file, and the error names the file asked for, not a temporary one."""
    from dualpixel.io.atomic import atomic_path, check_writable

    with pytest.raises(OutputFileError, match=r"^/proc/out\.png: could not be written"):
        check_writable("/proc/out.png")
    with pytest.raises(OutputFileError, match=r"^/proc/out\.png: ") as raised:
        with atomic_path("/proc/out.png"):
            pass
    assert "partial" not in str(raised.value)
    check_writable(tmp_path / "fine.png")  # a writable folder: nothing left behind
    assert os.listdir(tmp_path) == []
    views = tmp_path / "views"
    views.mkdir()
    for name in ("left.png", "right.png"):
        cv2.imwrite(str(views / name), np.full((32, 48, 3), 128, np.uint8))
    result = CliRunner().invoke(cli, ["deblur", "--left", str(views / "left.png"), "--right",
                                      str(views / "right.png"), "-o", "/proc/out.png"])
    assert result.exit_code == 1
    assert "Error: /proc/out.png: could not be written" in result.output
    assert "deblurring" not in result.output and "Traceback" not in result.output
