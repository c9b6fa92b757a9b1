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
