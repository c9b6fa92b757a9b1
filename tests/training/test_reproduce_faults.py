"""Issue #76: `reproduce` killed (SIGKILL, its process group) in the middle of its phases and
rerun ends where an uninterrupted run ends: the shipped weights equal, tensor for tensor, and
the evaluation the same."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml
from safetensors.torch import load_file

from tests.training.test_recipe import TINY_MACHINE, TINY_PHASE, TINY_SCENES

RECIPE = {
    "name": "tiny",
    "data": [{"name": "scenes", "scenes": {**TINY_SCENES, "seed": 1}},
             {"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set1"],
                                         "max_layers": 40, "noise_sigmas": [0.01]}}],
    "train": {"model": "rdpd", "synthetic_data": "synth", "val_data": "synth",
              "val_split": "train", **{**TINY_PHASE, "epochs": 3}, "width": 0.125},
    "phases": [{"name": "first"}, {"name": "second", "set": {"learning_rate": 1e-4}}],
    "ship": {"tag": "rdpd.v1", "doc": "a tiny model"},
    "evaluate": [{"name": "synth", "dataset": "synth", "split": "train"}],
}


def _reproduce(recipe: Path, output: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "dualpixel", "reproduce", str(recipe), "--output", str(output),
         "--workers", "1", "--loader-workers", str(TINY_MACHINE["workers"]), "--threads",
         str(TINY_MACHINE["threads"]), "--device", TINY_MACHINE["device"], "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})


def _shipped(run: Path) -> dict:
    (weights,) = (run / "ship").glob("*.safetensors")
    return load_file(str(weights))


def test_a_killed_reproduce_resumes_to_the_uninterrupted_result(tmp_path):
    recipe = tmp_path / "recipes" / "tiny.yaml"
    recipe.parent.mkdir()
    recipe.write_text(yaml.safe_dump(RECIPE, sort_keys=False))
    reference = _reproduce(recipe, tmp_path / "reference")
    assert reference.wait(timeout=600) == 0, reference.stdout.read().decode()[-3000:]

    killed = _reproduce(recipe, tmp_path / "killed")
    history = tmp_path / "killed" / "phases" / "first" / "history.jsonl"
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and killed.poll() is None:
        if history.is_file() and history.read_text().count("\n") >= 1:  # mid-phase
            os.killpg(killed.pid, signal.SIGKILL)
            break
        time.sleep(0.05)
    assert killed.wait(timeout=60) == -signal.SIGKILL, "the run ended before it was killed"
    assert not (tmp_path / "killed" / "ship").exists() or not list(
        (tmp_path / "killed" / "ship").glob("*.safetensors"))
    rerun = _reproduce(recipe, tmp_path / "killed")
    assert rerun.wait(timeout=600) == 0, rerun.stdout.read().decode()[-3000:]

    ours, theirs = _shipped(tmp_path / "killed"), _shipped(tmp_path / "reference")
    assert ours.keys() == theirs.keys()
    assert all(bool((ours[key] == theirs[key]).all()) for key in ours)
    scores = [{method: {k: v for k, v in rows["combined"].items() if k != "seconds"}
               for method, rows in json.loads(
                   (run / "eval" / "synth" / "summary.json").read_text())["summary"].items()}
              for run in (tmp_path / "killed", tmp_path / "reference")]
    assert scores[0] == scores[1]  # all but the time taken
