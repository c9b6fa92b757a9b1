"""The README's and the model card's results tables are generated, and the committed ones match."""

from pathlib import Path
from types import SimpleNamespace

import pytest

from dualpixel.errors import InputFileError
from dualpixel.evaluation.tables import (
    dev_scene_table,
    held_out_table,
    outside_family_table,
    target_free_table,
    update_documents,
    weights_table,
)

ROOT = Path(__file__).resolve().parents[2]


def test_dev_scene_gains_and_means_come_from_the_results():
    rows = [{"evaluation": "canon-dp-real", "image": f"scene_0{k}", "psnr": str(25.0 + k),
             "input_psnr": "24.0"} for k in range(2)]
    rows.append({"evaluation": "synth", "image": "seq_1", "psnr": "30", "input_psnr": "20"})
    table = dev_scene_table({"a.v1": rows}, {"a.v1": "`a.v1`"}).splitlines()
    assert table[0] == "| scene | 840x512: `a.v1` |"
    assert table[2:] == ["| 00 | +1.00 |", "| 01 | +2.00 |", "| mean | **+1.50** |"]


def test_held_out_table_means_every_evaluation_but_the_dev_scenes():
    rows = [{"evaluation": "phone", "image": f"seq_{k}", "psnr": str(30.0 + k),
             "input_psnr": str(27.0 + 2 * k)} for k in range(2)]
    rows.append({"evaluation": "canon-dp-real", "image": "scene_00", "psnr": "26",
                 "input_psnr": "25"})
    table = held_out_table({"a.v1": rows, "b.v2": []},
                           {"a.v1": "`a.v1`", "b.v2": "`b.v2`"}).splitlines()
    assert table[0] == "| held-out frames | images | `a.v1`: PSNR (gain) |"  # b has none
    assert table[2:] == ["| phone | 2 | 30.50 (+2.50) |"]


def test_target_free_means_per_camera_group():
    def row(pair, method, change, overshoot):
        return {"pair": pair, "method": method, "brightness_change": str(change),
                "local_brightness": "0.01", "overshoot": str(overshoot),
                "in_focus_change": "1.0", "sharpness_gain": "nan"}

    rows = [row("dp-real-nogt/sdirt-01", "m", 0.01, 1.0),
            row("dp-real-nogt/sdirt-02", "m", -0.03, 0.5),
            row("canon-dp-real/scene_00", "m", 0.0, 0.2), row("canon-dp-real/scene_00", "x", 0, 0)]
    table = target_free_table(rows, {"m": "`m`"}).splitlines()
    assert table[2] == "| 2 Canon EOS R6 II | `m` | -1.00 (-3.00) | 1.00 | 0.75 | 1.00 | nan |"
    assert table[3].startswith("| 1 Canon dev, 840x512 | `m` | +0.00")
    assert len(table) == 4  # the method not asked for is left out


def test_outside_family_gains_and_losing_images_per_camera():
    def row(evaluation, image, method, given, psnr):
        return {"evaluation": evaluation, "image": image, "method": method,
                "input_psnr": str(given), "psnr": str(psnr)}

    rows = [row("disk", "seq_1", "m+tied", 20, 23), row("disk", "seq_2", "m+tied", 30, 29),
            row("disk", "seq_1", "other", 20, 40), row("paper", "seq_1", "m+tied", 20, 21),
            row("paper", "seq_1", "n", 20, 22)]
    table = outside_family_table(rows, {"m+tied": "`m` (tied)", "n": "`n`"}).splitlines()
    assert table[0] == "| model | disk (2) | paper (1) |"  # the unasked method left out
    assert table[2:] == ["| `m` (tied) | +1.00 (1 lose) | +1.00 |", "| `n` | – | +2.00 |"]


def test_weights_table_reads_the_registry_rows():
    row = SimpleNamespace(metrics={"canon-dp-real": {"psnr": 26.5, "ssim": 0.7812}},
                          output={"brightness": "tied", "flips": True})
    table = weights_table({"a.v2": row}, {"a": "a.v2"}, "a").splitlines()
    assert table[3] == "| `a.v2` (a, the default) | 26.50 / 0.781 | – | flips, tied |"
    assert table[2].startswith("| blurred input") and table[4].startswith("| published DPDNet")
    results = {"a.v2": [{"evaluation": "canon-dp-real", "image": f"scene_0{k}",
                         "psnr": str(26.0 + k), "ssim": "0.8"} for k in range(2)]}
    table = weights_table({"a.v2": row}, {"a": "a.v2"}, "a", results).splitlines()
    assert table[3] == "| `a.v2` (a, the default) | 26.50 / 0.800 | – | flips, tied |"  # as run


def test_a_document_without_its_markers_is_refused(tmp_path):
    (tmp_path / "docs" / "results").mkdir(parents=True)
    (tmp_path / "docs" / "results" / "target-free.csv").write_text(
        "pair,method,brightness_change\n")
    (tmp_path / "docs" / "results" / "outside-family.csv").write_text(
        "evaluation,image,method,input_psnr,psnr\n")
    (tmp_path / "README.md").write_text("no markers\n")
    with pytest.raises(InputFileError, match="generated: weights"):
        update_documents(tmp_path, check=True)


def test_the_committed_tables_are_the_generated_ones():
    assert update_documents(ROOT, check=True) == [], (
        "regenerate them: python -m dualpixel.evaluation.tables")
