"""eval on linear raw views with a ground truth (a phone's DP captures): the views go to the model
as deblur feeds them, and the scores are taken in the files' own raw values."""

import csv
import json

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

import dualpixel
from dualpixel.cli.main import cli
from dualpixel.evaluation.metrics import psnr
from dualpixel.io.dpdd import role_folder

BLACK, WHITE = 1024, 16383


@pytest.fixture()
def raw_dataset(tmp_path):
    """One 14-bit grey pair above a black level, its combined image and a sharp target."""
    rng = np.random.default_rng(0)
    sharp = cv2.resize(rng.uniform(0.02, 0.4, (12, 16)).astype(np.float32), (128, 96),
                       interpolation=cv2.INTER_NEAREST)
    blurred = cv2.GaussianBlur(sharp, (0, 0), 1.5)
    images = {"left": np.roll(blurred, -1, axis=1), "right": np.roll(blurred, 1, axis=1),
              "combined": blurred, "target": sharp}
    root = tmp_path / "pixel"
    for role, light in images.items():
        folder = role_folder(root, "test", role)
        folder.mkdir(parents=True)
        raw = np.rint(BLACK + light * (WHITE - BLACK)).astype(np.uint16)
        cv2.imwrite(str(folder / "capture.png"), raw)
    return root


def _model_psnr(out):
    rows = list(csv.DictReader((out / "per_image.csv").open()))
    return float(next(r for r in rows if r["method"] != "input")["psnr"])


def test_eval_feeds_linear_views_as_deblur_does(raw_dataset, tmp_path, tiny_checkpoint):
    root = raw_dataset
    out = tmp_path / "linear"
    result = CliRunner().invoke(cli, [
        "eval", "--dataset", str(root), "--checkpoint", str(tiny_checkpoint), "--no-niqe",
        "--figures", "0", "--device", "cpu", "--precision", "fp32", "-o", str(out),
        "--encoding", "linear", "--black-level", str(BLACK), "--white-level", str(WHITE)])
    assert result.exit_code == 0, result.output
    # the same as deblur's linear mode on the files' values, scored in them
    files = [cv2.imread(str(role_folder(root, "test", role) / "capture.png"), -1) / 65535.0
             for role in ("left", "right", "target")]
    output = dualpixel.deblur(files[0], files[1], model=str(tiny_checkpoint), device="cpu",
                              precision="fp32", encoding="linear", black_level=BLACK / 65535,
                              white_level=WHITE / 65535)
    assert _model_psnr(out) == pytest.approx(psnr(np.repeat(output[..., None], 3, axis=2),
                                                  np.repeat(files[2][..., None], 3, axis=2)),
                                             abs=0.01)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["view_findings"] == []
    assert summary["encoding"] == {"encoding": "linear", "black_level": BLACK,
                                   "white_level": WHITE}


def test_eval_warns_when_raw_views_are_scored_as_display_values(raw_dataset, tmp_path):
    root = raw_dataset
    out = tmp_path / "display"
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(root), "--no-model",
                                      "--no-niqe", "--figures", "0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "look linear" in result.output and "--encoding linear" in result.output
    codes = [f["code"] for f in json.loads((out / "summary.json").read_text())["view_findings"]]
    assert codes == ["looks-linear"]


def test_eval_refuses_linear_views_without_their_levels(raw_dataset, tmp_path):
    root = raw_dataset
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(root), "--encoding", "linear",
                                      "--white-level", "16383", "-o", str(tmp_path / "x")])
    assert result.exit_code == 2 and "--black-level" in result.output
    assert "Traceback" not in result.output
