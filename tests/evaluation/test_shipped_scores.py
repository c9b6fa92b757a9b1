"""Issue #76: the shipped default re-scored on the dev scenes of ``../shared`` as it runs
(its own output settings, float32 as its results were measured), against the per-scene figures
of its results CSV (``docs/results``) and the means the README and the registry print."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest

import dualpixel
from dualpixel.io.images import read_rgb
from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, WEIGHTS

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ALIASES.get(DEFAULT_CHECKPOINT, DEFAULT_CHECKPOINT)


@pytest.mark.parametrize("dataset", ["canon-dp-real", "canon-dp-real-hd"])
def test_the_default_scores_what_the_documents_say(shared_dir, dataset):
    rows = [r for r in csv.DictReader((ROOT / "docs" / "results" / f"{DEFAULT}.csv").open())
            if r["evaluation"] == dataset]
    assert len(rows) == 7
    scores = {}
    for row in rows:
        scene = shared_dir / "data" / dataset / row["image"]
        output = dualpixel.deblur(read_rgb(scene / "view0.png"), read_rgb(scene / "view1.png"),
                                  device="cpu", precision="fp32")
        scores[row["image"]] = dualpixel.psnr(output, read_rgb(scene / "target.png"))
        assert scores[row["image"]] == pytest.approx(float(row["psnr"]), abs=0.002), row
    mean = float(np.mean(list(scores.values())))
    assert mean == pytest.approx(WEIGHTS[DEFAULT].metrics[dataset]["psnr"], abs=0.005)
    line = next(line for line in (ROOT / "README.md").read_text().splitlines()
                if line.startswith(f"| `{DEFAULT}`"))
    column = 1 if dataset == "canon-dp-real" else 2
    printed = re.findall(r"(\d+\.\d\d) / ", line)[column - 1]
    assert mean == pytest.approx(float(printed), abs=0.005)
