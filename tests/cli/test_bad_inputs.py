"""Bad input, command by command: a clear message naming the file or option, the
right exit status (2: a bad option, 1: a failure), and never a Python traceback."""

import errno

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner
from safetensors.torch import save_file

from dualpixel.cli.main import cli
from dualpixel.errors import OutputFileError
from dualpixel.io.atomic import atomic_path
from dualpixel.models import build_model, save_model
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    rng = np.random.default_rng(0)
    for name, size in (("l", (40, 48)), ("r", (40, 48)), ("small", (30, 48))):
        cv2.imwrite(str(root / f"{name}.png"), rng.integers(0, 255, (*size, 3), np.uint8))
    (root / "frames").mkdir()
    cv2.imwrite(str(root / "frames" / "a.png"), rng.integers(0, 255, (40, 48, 3), np.uint8))
    torch.manual_seed(0)
    save_model(root / "tiny.safetensors", build_model("rdpd", width=0.125, residual=True))
    psf = np.zeros((2, 9, 9))
    psf[:, 4, 4] = 1.0
    np.savez(root / "psfs.npz", left=psf, right=psf * 0.5)
    np.save(root / "zeros.npy", np.zeros((2, 9, 9)))
    write_scene_folder(root / "scenes", 1, SceneConfig(width=32, height=24, frames=1, leaves=3),
                       progress=False)
    return root


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def assert_clear(result, status: int, *names: str):
    """Exit ``status``, a message that names each of ``names``, no traceback."""
    assert result.exit_code == status, result.output
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    for name in names:
        assert name in result.output, (name, result.output)
    if status == 2:  # a usage error shows the subcommand's usage line
        assert "Usage: cli " in result.output and "COMMAND" not in result.output.splitlines()[0]


CUDA_ABSENT = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is present here")


# --- devices -------------------------------------------------------------------------------
@pytest.mark.parametrize("device", ["foo", pytest.param("cuda", marks=CUDA_ABSENT)])
def test_devices(files, tmp_path, device):
    assert_clear(invoke("synth", "--input", files / "scenes", "--output", tmp_path / "s",
                        "--device", device), 2, device)
    assert_clear(invoke("deblur", "--left", files / "l.png", "--right", files / "r.png",
                        "--output", tmp_path / "o.png", "--checkpoint", files / "tiny.safetensors",
                        "--device", device), 2, device)
    config = tmp_path / "c.yaml"
    config.write_text(f"synthetic_data: {files / 'scenes'}\ndevice: {device}\n")
    assert_clear(invoke("train", "--config", config, "--output", tmp_path / "t"), 2, device)


# --- output paths --------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["out", "out.xyz", "existing_folder"])
def test_output_paths(files, tmp_path, name):
    output = tmp_path / name
    if name == "existing_folder":
        output.mkdir()
    shown = name
    assert_clear(invoke("deblur", "--left", files / "l.png", "--right", files / "r.png",
                        "--output", output, "--checkpoint", files / "tiny.safetensors"), 1, shown)
    assert_clear(invoke("psf", "--output", output), 1 if name != "existing_folder" else 2, shown)
    assert_clear(invoke("pattern", "--kind", "disks", "--size", "64x48", "--output", output),
                 1 if name != "existing_folder" else 2, shown)


def test_sixteen_bits_into_jpeg_are_rescaled_not_clipped(files, tmp_path):
    image = np.full((40, 48, 3), 30000, np.uint16)
    cv2.imwrite(str(tmp_path / "l16.png"), image)
    cv2.imwrite(str(tmp_path / "r16.png"), image)
    result = invoke("deblur", "--left", tmp_path / "l16.png", "--right", tmp_path / "r16.png",
                    "--output", tmp_path / "o.jpg", "--checkpoint", files / "tiny.safetensors")
    assert result.exit_code == 0, result.output
    written = cv2.imread(str(tmp_path / "o.jpg"))
    assert 80 < written.mean() < 160  # about 30000 / 257 = 117, not white


def test_full_disk_names_the_path(tmp_path):
    target = tmp_path / "x.npy"
    with pytest.raises(OutputFileError, match=r"x\.npy: no space left on device"):
        with atomic_path(target):
            raise OSError(errno.ENOSPC, "No space left on device")
    assert not list(tmp_path.iterdir())  # nothing half-written left behind


@pytest.fixture
def full_disk(tmp_path):
    """A 64 KiB file system, filled (a tmpfs; skipped where this user may not mount one)."""
    import subprocess

    folder = tmp_path / "full"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                             capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a small file system here")
    try:
        (folder / "fill").write_bytes(b"x" * 60_000)
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


@pytest.mark.parametrize("command", [
    ["deblur", "--left", "{v}/l.png", "--right", "{v}/r.png", "--output", "{f}/out.png",
     "--checkpoint", "{c}"],
    ["psf", "--output", "{f}/psf.png", "--radii=-12,12"],
    ["pattern", "--kind", "disks", "--size", "640x480", "--spacing", "60", "--output",
     "{f}/p.png"],
    ["scenes", "--output", "{f}/scenes", "--sequences", "1", "--frames", "1", "--size", "96x64"],
])
def test_a_full_disk_names_the_output_and_leaves_nothing_half_written(command, full_disk,
                                                                      tiny_checkpoint, tmp_path):
    views = tmp_path / "views"
    views.mkdir()
    rng = np.random.default_rng(0)
    for name in ("l", "r"):
        cv2.imwrite(str(views / f"{name}.png"), rng.integers(0, 255, (64, 96, 3), np.uint8))
    args = [a.format(v=views, f=full_disk, c=tiny_checkpoint) for a in command]
    result = invoke(*args)
    assert result.exit_code == 1, result.output
    assert "no space left on device" in result.output and str(full_disk) in result.output
    assert "Traceback" not in result.output
    leftovers = [p.name for p in full_disk.rglob("*") if p.is_file() and p.name != "fill"]
    assert not [n for n in leftovers if "tmp" in n or "partial" in n], leftovers


def test_eval_refuses_an_output_file_before_evaluating(files, tmp_path):
    (tmp_path / "report").write_text("a file")
    assert_clear(invoke("eval", "--dataset", files, "--output", tmp_path / "report"), 2,
                 "--output", "report")


# --- values that cannot give a right result --------------------------------------------------
def test_synth_values(files, tmp_path):
    for option, value, named in (("--noise-sigmas", "nan", "--noise-sigmas"),
                                 ("--noise-sigmas", "-0.1", "noise_sigmas"),
                                 ("--max-depth", "0", "max_depth"),
                                 ("--depth-scale", "0", "depth_scale")):
        assert_clear(invoke("synth", "--input", files / "scenes", "--output", tmp_path / "s",
                            option, value), 2, named)
    assert not (tmp_path / "s" / "manifest.jsonl").exists()


def test_scenes_into_a_folder_of_other_settings(files, tmp_path):
    assert invoke("scenes", "--output", tmp_path / "sc", "--sequences", "1", "--frames", "1",
                  "--size", "32x24").exit_code == 0
    assert_clear(invoke("scenes", "--output", tmp_path / "sc", "--sequences", "1", "--frames",
                        "1", "--size", "40x24"), 1, "sc", "width")
    assert_clear(invoke("scenes", "--output", tmp_path / "sc", "--sequences", "1", "--frames",
                        "1", "--size", "32x24", "--seed", "5"), 1, "seed")


@pytest.mark.parametrize("seed", ["-5", "1.5", str(2**63)])
def test_seeds_out_of_range_are_refused_before_any_work(files, tmp_path, seed):
    assert_clear(invoke("scenes", "--output", tmp_path / "sc", "--sequences", "1", "--seed", seed),
                 2, "--seed")
    assert_clear(invoke("synth", "--input", files / "scenes", "--output", tmp_path / "sy",
                        "--seed", seed), 2, "--seed")
    assert_clear(invoke("demo", "--output", tmp_path / "d", "--seed", seed), 2, "--seed")
    assert not any((tmp_path / name).exists() for name in ("sc", "sy", "d"))


def test_export(files, tmp_path):
    assert_clear(invoke("export", "--checkpoint", files / "tiny.safetensors", "--format",
                        "safetensors-fp16", "--output", tmp_path / "x.onnx"), 2, "--output",
                 ".safetensors")
    assert_clear(invoke("export", "--checkpoint", files / "tiny.safetensors", "--output",
                        tmp_path / "x.onnx", "--size", "0x0"), 2, "0x0", "--size")


def test_checkpoint_metadata_without_a_key(files, tmp_path):
    path = tmp_path / "broken.safetensors"
    save_file({"w": torch.zeros(1)}, str(path), metadata={"format": "dualpixel-model-1",
                                                            "model": "rdpd"})
    assert_clear(invoke("deblur", "--left", files / "l.png", "--right", files / "r.png",
                        "--output", tmp_path / "o.png", "--checkpoint", path), 1,
                 "broken.safetensors", "width")


def test_deblur_views(files, tmp_path):
    assert_clear(invoke("deblur", "--left", files / "frames", "--right", files / "r.png",
                        "--output", tmp_path / "o", "--checkpoint", files / "tiny.safetensors"),
                 1, "r.png", "folder")
    assert_clear(invoke("deblur", "--left", files / "l.png", "--right", files / "small.png",
                        "--output", tmp_path / "o.png", "--checkpoint",
                        files / "tiny.safetensors"), 1, "small.png", "differs")
    # a tile at or below the old fixed overlap of 192 works with the derived default
    result = invoke("deblur", "--left", files / "l.png", "--right", files / "r.png", "--output",
                    tmp_path / "t.png", "--checkpoint", files / "tiny.safetensors", "--tile", "32")
    assert result.exit_code == 0, result.output
    # ... with the library's warning as a warning of the command, not of generated code
    assert "Warning: tile 32 px" in result.output and "<string>" not in result.output


def test_train_refusals(files, tmp_path, tiny_synthetic_dataset):
    assert_clear(invoke("train", "--set", f"synthetic_data={tiny_synthetic_dataset}", "--set",
                        "nope=1", "--output", tmp_path / "t"), 2, "--set", "nope")
    unfinished = tmp_path / "unfinished"
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset

    synthesize_dataset(files / "scenes", "rgbd", unfinished,
                       SynthConfig(lens_sets=("set0",), max_layers=8), progress=False, limit=0)
    assert_clear(invoke("train", "--set", f"synthetic_data={unfinished}", "--set", "epochs=1",
                        "--output", tmp_path / "t2"), 1, "dataset.json", "unfinished")
    settings = [f"synthetic_data={tiny_synthetic_dataset}", "synthetic_as_frames=true",
                "patch_size=32", f"frame_store={files / 'l.png'}"]
    assert_clear(invoke("train", *(a for s in settings for a in ("--set", s)), "--output",
                        tmp_path / "t3"), 1, "l.png", "must be a folder")


# --- memory ---------------------------------------------------------------------------------
def test_requests_too_large_for_memory(tmp_path):
    assert_clear(invoke("psf", "--radii", "5000", "--output", tmp_path / "p.png"), 2,
                 "GiB", "14203x14203")
    assert_clear(invoke("pattern", "--kind", "squares", "--size", "200000x200000", "--output",
                        tmp_path / "p.png"), 2, "16384", "200000x200000")  # bounded first


# --- calibration ----------------------------------------------------------------------------
def test_fit_psf_inputs(files, tmp_path):
    report = tmp_path / "r"
    for right, named in ((files / "l.png", "l.png"), (files / "zeros.npy", "sum to zero")):
        assert_clear(invoke("calibrate", "fit-psf", "--left", files / "psfs.npz", "--right",
                            right, "--report", report), 1, named)
    for limit in ("0", "-1"):
        assert_clear(invoke("calibrate", "fit-psf", "--left", files / "psfs.npz", "--right",
                            files / "psfs.npz", "--report", report, "--limit", limit), 2,
                     "--limit")
    from dualpixel.calibration.measured_psfs import load_measured_psfs

    # the npz's right array for --right, not its left one
    np.testing.assert_array_equal(load_measured_psfs(files / "psfs.npz", "right")[:, 4, 4], 0.5)


def test_estimate_psf_inputs(files, tmp_path):
    base = ["calibrate", "estimate-psf", "--left", files / "l.png", "--output", tmp_path / "e.npz"]
    for extra, named in ((["--right", files / "r.png", "--radius", "0"], "radius"),
                         (["--right", files / "r.png", "--radius", "-3"], "radius"),
                         (["--right", files / "r.png", "--radius", "3", "--lam", "-1"], "lam")):
        assert_clear(invoke(*base, *extra), 2, named)
    assert_clear(invoke(*base, "--right", files / "small.png", "--radius", "3"), 1, "small.png",
                 "differs")


def test_fit_distortion_inputs(files, tmp_path):
    pattern = tmp_path / "pattern.png"
    assert invoke("pattern", "--kind", "squares", "--size", "96x64", "--spacing", "16",
                  "--output", pattern).exit_code == 0
    noise = tmp_path / "noise.png"
    cv2.imwrite(str(noise), np.random.default_rng(1).integers(0, 255, (64, 96, 3), np.uint8))
    assert_clear(invoke("calibrate", "fit-distortion", "--capture", noise, "--pattern", pattern,
                        "--working-width", "96"), 2, "correlation")
    assert_clear(invoke("calibrate", "fit-distortion", "--capture", noise, "--pattern", pattern,
                        "--working-width", "0"), 2, "--working-width")


# --- statistics and NIQE --------------------------------------------------------------------
def test_stats_and_niqe_name_the_file(files, tmp_path):
    (tmp_path / "empty").mkdir()
    assert_clear(invoke("stats", tmp_path / "empty"), 1, "empty")
    small = tmp_path / "small"
    small.mkdir()
    cv2.imwrite(str(small / "tiny.png"), np.zeros((50, 50, 3), np.uint8))
    assert_clear(invoke("niqe", "fit", "--images", small, "--output", tmp_path / "m.npz"), 1,
                 "tiny.png", "96x96")


def test_quiet_silences_progress_bars(tmp_path):
    import subprocess
    import sys

    args = ["scenes", "--sequences", "1", "--frames", "1", "--size", "32x24"]
    loud = subprocess.run([sys.executable, "-m", "dualpixel", *args, "-o", str(tmp_path / "a")],
                          capture_output=True, text=True, check=True)
    quiet = subprocess.run([sys.executable, "-m", "dualpixel", "-q", *args, "-o",
                            str(tmp_path / "b")], capture_output=True, text=True, check=True)
    assert "rendering scenes" in loud.stderr
    assert "rendering scenes" not in quiet.stderr and "wrote 1 sequences" in quiet.stdout


def test_console_script_freezes_the_collector_only_when_the_process_ends():
    """``run`` (the console script, ``python -m dualpixel``) keeps the process's objects out of
    the exit's last collections and passes the command's exit status on; ``cli.main`` called
    from Python leaves the collector as it is."""
    import subprocess
    import sys

    probe = ("import gc, sys\n"
             "from dualpixel.cli.main import cli, run\n"
             "cli.main(['--version'], standalone_mode=False)\n"
             "print('after cli.main', gc.get_freeze_count())\n"
             "sys.argv = ['dualpixel', 'deblur', '--left', 'no-such-view.png']\n"
             "try:\n"
             "    run()\n"
             "except SystemExit as end:\n"
             "    print('after run', gc.get_freeze_count() > 0, end.code)\n")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            check=True)
    assert "after cli.main 0" in result.stdout
    assert "after run True 2" in result.stdout
    assert "no-such-view.png" in result.stderr and "Traceback" not in result.stderr


def test_console_script_ends_a_deblur_at_once_but_keeps_what_exit_does(files, tmp_path):
    """After a deblur that succeeded, ``run`` ends the process without the interpreter's
    teardown: the exit handlers still run and the output is flushed into a pipe; a thread
    still working is waited for; a failure, or another command, ends the usual way."""
    import subprocess
    import sys

    probe = ("import atexit, os, sys, threading, time\n"
             "from dualpixel.cli.main import run\n"
             "atexit.register(lambda: print('exit handlers ran', flush=True))\n"
             "def late():  # still working when the command has written its output\n"
             "    for _ in range(6000):\n"
             "        if os.path.exists(sys.argv[-1]):\n"
             "            break\n"
             "        time.sleep(0.01)\n"
             "    time.sleep(0.5)\n"
             "    print('thread done')\n"
             "if sys.argv[1] == 'thread':\n"
             "    threading.Thread(target=late).start()\n"
             "sys.argv = ['dualpixel', *sys.argv[2:]]\n"
             "try:\n"
             "    run()\n"
             "except SystemExit as end:\n"
             "    print('ended the usual way', end.code)\n")
    deblur = ["deblur", "--left", str(files / "l.png"), "--right", str(files / "r.png"),
              "--checkpoint", str(files / "tiny.safetensors"), "-o"]

    def ended(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", probe, *args], capture_output=True,
                              text=True, timeout=300)

    quick = ended("", *deblur, str(tmp_path / "a.png"))
    assert quick.returncode == 0, quick.stderr
    assert "wrote 1 frame(s)" in quick.stdout and "exit handlers ran" in quick.stdout
    assert "ended the usual way" not in quick.stdout
    assert cv2.imread(str(tmp_path / "a.png")).shape == (40, 48, 3)
    waited = ended("thread", *deblur, str(tmp_path / "b.png"))
    assert "thread done" in waited.stdout and "ended the usual way 0" in waited.stdout
    failed = ended("", *deblur[:-3], "--checkpoint", str(files / "psfs.npz"), "-o",
                   str(tmp_path / "c.png"))
    assert "ended the usual way 1" in failed.stdout and "psfs.npz" in failed.stderr
    other = ended("", "--version")
    assert "ended the usual way 0" in other.stdout and "exit handlers ran" in other.stdout


def test_quiet_run_from_python_leaves_later_commands_their_bars(tmp_path, monkeypatch):
    """``--quiet`` silences worker processes through the environment; a command run in this
    process (a notebook, a test) must not leave it silenced for the commands after it."""
    import os

    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    args = ["scenes", "--sequences", "1", "--frames", "1", "--size", "32x24", "-o"]
    result = CliRunner().invoke(cli, ["-q", *args, str(tmp_path / "a")])
    assert result.exit_code == 0, result.output
    assert "TQDM_DISABLE" not in os.environ
    monkeypatch.setenv("TQDM_DISABLE", "0")  # a setting of the user's own is put back as it was
    assert CliRunner().invoke(cli, ["-q", *args, str(tmp_path / "b")]).exit_code == 0
    assert os.environ["TQDM_DISABLE"] == "0"


def test_eval_names_a_defocus_map_of_the_wrong_size(files, tmp_path, tiny_synthetic_dataset):
    import shutil

    copy = tmp_path / "ds"
    shutil.copytree(tiny_synthetic_dataset, copy)
    bad = sorted((copy / "train_c" / "defocus").rglob("*.npy"))[0]
    np.save(bad, np.zeros((5, 5), np.float32))
    assert_clear(invoke("eval", "--dataset", copy, "--split", "train", "--checkpoint",
                        files / "tiny.safetensors", "--output", tmp_path / "r", "--no-niqe"),
                 1, bad.name, "defocus map is (5, 5)")


def test_export_without_the_onnx_extra_names_it(tmp_path, monkeypatch, tiny_checkpoint):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("onnx", "onnxscript") else real(name, *a))
    result = CliRunner().invoke(cli, ["export", "--checkpoint", str(tiny_checkpoint), "-o",
                                      str(tmp_path / "m.onnx")])
    assert result.exit_code == 2 and "dualpixel[onnx]" in result.output, result.output
    assert "Traceback" not in result.output and not (tmp_path / "m.onnx").exists()
