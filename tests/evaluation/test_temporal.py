"""Issue #75: flicker, the frame-to-frame change of a method in static regions of a sequence,
beside the target's own."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.evaluation.temporal import FlickerMeter


def test_flicker_of_known_sequences():
    rng = np.random.default_rng(0)
    scene = rng.uniform(0.2, 0.8, (40, 60, 3)).astype(np.float32)
    meter = FlickerMeter()
    for t in range(4):
        target = scene.copy()
        target[:, 40:] = rng.uniform(0.2, 0.8, (40, 20, 3))  # a moving part: left out
        flickering = np.clip(target + (0.02 if t % 2 else -0.02), 0, 1)  # +-5.1 levels
        meter.add("seq", target, {"steady": target, "flickering": flickering})
    table = meter.table()
    # the target itself changes a little at the moving part's smoothed border
    assert table["steady"]["change"] == table["steady"]["target_change"] < 0.5
    assert table["steady"]["excess"] == pytest.approx(0.0, abs=1e-4)
    assert table["flickering"]["excess"] == pytest.approx(2 * 0.02 * 255, rel=0.05)
    assert table["flickering"]["pairs"] == 3
    # a new sequence starts afresh: its first frame is compared with nothing
    meter.add("other", scene, {"steady": scene, "flickering": scene})
    assert meter.table()["flickering"]["pairs"] == 3
    assert FlickerMeter().table() == {}


def test_eval_reports_flicker_on_sequences(tiny_synthetic_dataset, tiny_checkpoint, tmp_path):
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(tiny_synthetic_dataset),
                                      "--split", "train", "--checkpoint", str(tiny_checkpoint),
                                      "--output", str(tmp_path / "r"), "--no-niqe",
                                      "--figures", "0", "--device", "cpu"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert set(summary["flicker"]) == {"input", "tiny"}
    for row in summary["flicker"].values():
        assert row["pairs"] == 8  # 4 sequences of 3 frames
        assert row["excess"] == pytest.approx(row["change"] - row["target_change"], abs=1e-3)
    assert "flicker" in (tmp_path / "r" / "summary.md").read_text()


def test_scores_by_frame_position():
    from dualpixel.evaluation.evaluate import ImageResult, by_position, position_markdown

    def row(method, position, value):
        return ImageResult(f"s/{position}", method, "", value, 0.5, 0.1, None, None,
                           position=position)

    results = [row("model", 0, 30.0), row("model", 1, 31.0), row("model", 0, 32.0),
               row("model", 1, 35.0), row("input", 0, 25.0), row("input", 1, 26.0),
               ImageResult("single", "model", "", 99.0, 0.5, 0.1, None, None)]
    table = by_position(results)
    assert [(e["position"], e["psnr"], e["count"]) for e in table["model"]] == \
        [(0, 31.0, 2), (1, 33.0, 2)]  # the single image (no position) is left out
    assert [e["psnr"] for e in table["input"]] == [25.0, 26.0]
    assert "| model | 31.00 | 33.00 |" in position_markdown(table)
    assert by_position([ImageResult("single", "model", "", 1.0, 0.5, 0.1, None, None)]) == {}


def test_afresh_resets_the_state_before_every_frame(tiny_synthetic_dataset):
    """A stateful stand-in model (each call adds a step more than the last, since its reset):
    carried, the second and third frames of a sequence differ from the first; afresh, every
    frame is the first, so all positions score alike."""
    from dualpixel.data.layout import discover_dp_dataset
    from dualpixel.evaluation.evaluate import by_position, evaluate, examples_from_sequences

    examples = examples_from_sequences(discover_dp_dataset(tiny_synthetic_dataset, "train"))
    calls = {"since_reset": 0, "resets": 0}

    def deblur(left, right):
        calls["since_reset"] += 1
        return np.clip((left + right) / 2 + 0.1 * calls["since_reset"], 0, 1)

    def reset():
        calls.update(since_reset=0, resets=calls["resets"] + 1)

    scored = {}
    for afresh in (False, True):
        calls["resets"] = 0
        results = evaluate(examples, deblur=deblur, reset=reset, progress=False, afresh=afresh)
        scored[afresh] = [e["psnr"] for e in by_position(results)["model"]]
        assert calls["resets"] == (12 if afresh else 4)  # 4 sequences of 3 frames
    assert [e.position for e in examples] == [0, 1, 2] * 4
    carried, fresh = scored[False], scored[True]
    assert carried[1] < carried[0] - 1 and carried[2] < carried[1]
    assert fresh == pytest.approx([carried[0]] * 3, abs=0.02)  # frames differ a little


def test_eval_reports_scores_by_position(tiny_synthetic_dataset, tiny_checkpoint, tmp_path):
    import csv

    result = CliRunner().invoke(cli, ["eval", "--dataset", str(tiny_synthetic_dataset),
                                      "--split", "train", "--checkpoint", str(tiny_checkpoint),
                                      "--output", str(tmp_path / "r"), "--no-niqe", "--afresh",
                                      "--figures", "0", "--device", "cpu"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["afresh"] is True
    with open(tmp_path / "r" / "per_image.csv") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] == "tiny"]
    for entry in summary["by_position"]["tiny"]:
        chosen = [float(r["psnr"]) for r in rows if r["position"] == str(entry["position"])]
        assert entry["count"] == len(chosen) == 4
        assert entry["psnr"] == pytest.approx(np.mean(chosen))
    assert "by frame position" in (tmp_path / "r" / "summary.md").read_text()
