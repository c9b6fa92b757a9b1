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


def _write_dataset(root, images, channels):
    """A DPDD-layout dataset of one capture, each image stored with ``channels`` channels."""
    for role, values in images.items():
        folder = role_folder(root, "test", role)
        folder.mkdir(parents=True)
        stored = values if channels == 1 else cv2.merge([values] * 3)
        cv2.imwrite(str(folder / "capture.png"), stored)


@pytest.fixture()
def raw_dataset(tmp_path):
    """One 14-bit grey pair above a black level, its combined image and a sharp target (patches
    of 7.5 px: on an 8-px grid they would read as a coder's blocks)."""
    rng = np.random.default_rng(0)
    sharp = cv2.resize(rng.uniform(0.02, 0.4, (12, 16)).astype(np.float32), (120, 90),
                       interpolation=cv2.INTER_NEAREST)
    blurred = cv2.GaussianBlur(sharp, (0, 0), 1.5)
    images = {"left": np.roll(blurred, -1, axis=1), "right": np.roll(blurred, 1, axis=1),
              "combined": blurred, "target": sharp}
    root = tmp_path / "pixel"
    _write_dataset(root, {role: np.rint(BLACK + light * (WHITE - BLACK)).astype(np.uint16)
                          for role, light in images.items()}, 1)
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


@pytest.fixture(scope="module")
def colour_checkpoint(tmp_path_factory):
    """A tiny residual RDPD whose correction differs per channel (an untrained one's is zero,
    so its three output channels would agree on grey views)."""
    import torch

    from dualpixel.models import build_model, save_model

    torch.manual_seed(1)
    model = build_model("rdpd", width=0.125, residual=True)
    with torch.no_grad():
        model.head[2].weight.copy_(torch.randn_like(model.head[2].weight))
        model.head[2].bias.copy_(torch.tensor([0.05, -0.05, 0.0]))
    path = tmp_path_factory.mktemp("colour") / "colour.safetensors"
    save_model(path, model)
    return path


@pytest.mark.parametrize("encoding", ["srgb", "linear"])
@pytest.mark.parametrize("channels", [1, 3])
def test_eval_scores_what_deblur_writes_for_grey_and_colour_files(raw_dataset, tmp_path,
                                                                  colour_checkpoint, channels,
                                                                  encoding):
    """Views of equal channels, stored as one channel or as three, display-encoded or raw:
    eval's model row is the score of the image ``deblur`` gives for those files (grey: one
    channel, from the mean of the model's three; colour: the model's three as they are)."""
    files = [cv2.imread(str(role_folder(raw_dataset, "test", role) / "capture.png"), -1)
             for role in ("left", "right", "combined", "target")]
    if encoding == "srgb":
        files = [np.rint((f / 65535.0) ** 0.45 * 255).astype(np.uint8) for f in files]
    root, out = tmp_path / f"views{channels}", tmp_path / f"eval{channels}"
    _write_dataset(root, dict(zip(("left", "right", "combined", "target"), files)), channels)
    levels = {"linear": ["--encoding", "linear", "--black-level", str(BLACK), "--white-level",
                         str(WHITE)], "srgb": []}[encoding]
    result = CliRunner().invoke(cli, [
        "eval", "--dataset", str(root), "--checkpoint", str(colour_checkpoint), "--no-niqe",
        "--figures", "0", "--device", "cpu", "--precision", "fp32", "-o", str(out), *levels])
    assert result.exit_code == 0, result.output
    full = np.iinfo(files[0].dtype).max
    views = [cv2.imread(str(role_folder(root, "test", role) / "capture.png"), -1) / full
             for role in ("left", "right", "target")]
    views = [v if v.ndim == 3 else v[..., None] for v in views]
    api_levels = ({"encoding": "linear", "black_level": BLACK / full,
                   "white_level": WHITE / full} if encoding == "linear" else {})
    output = dualpixel.deblur(views[0], views[1], model=str(colour_checkpoint), device="cpu",
                              precision="fp32", **api_levels)
    assert output.shape[2] == channels
    expected = psnr(np.repeat(output, 3 // channels, axis=2),
                    np.repeat(views[2], 3 // channels, axis=2))
    assert _model_psnr(out) == pytest.approx(expected, abs=1e-3)


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


def test_eval_names_a_right_view_of_other_channels(raw_dataset, tmp_path):
    right = role_folder(raw_dataset, "test", "right") / "capture.png"
    cv2.imwrite(str(right), cv2.merge([cv2.imread(str(right), -1)] * 3))
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(raw_dataset), "--no-model",
                                      "--no-niqe", "--figures", "0", "-o", str(tmp_path / "x")])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert str(right) in result.output and "grey" in result.output
