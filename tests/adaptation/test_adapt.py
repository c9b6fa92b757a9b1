"""``dualpixel adapt`` end to end on tiny data: a model fine-tuned to a camera from its DP
pairs alone, resumable, reported, and loadable as a shipped one."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.io.images import write_png
from tests.adaptation.test_formation import CAMERA, _views
from tests.calibration.test_camera import _texture


def _pairs(root, count=3, radius=5.0, with_target=False):
    for n in range(count):
        sharp = _texture(160, 224, 30 + n)
        left, right = _views(sharp, radius)
        folder = root / f"pair{n}"
        folder.mkdir(parents=True)
        write_png(folder / "left.png", np.clip(left, 0, 1), bit_depth=8)
        write_png(folder / "right.png", np.clip(right, 0, 1), bit_depth=8)
        if with_target:  # ignored (a folder of pairs with targets adapts as one without)
            write_png(folder / "target.png", np.clip(sharp, 0, 1), bit_depth=8)
    return root


SMALL = ["--scenes", "2", "--epochs", "2", "--iterations", "2", "--threads", "1",
         "--no-progress", "--formation-weight", "1", "--in-focus-weight", "1",
         "--patch-size", "64", "--scene-size", "128x96"]


@pytest.fixture
def small_settings(monkeypatch):
    """Batches of the test's size (the command's defaults are a photo's)."""
    import importlib

    module = importlib.import_module("dualpixel.adaptation.finetune")
    real = module.AdaptSettings

    def settings(**values):
        return real(**{"batch": 1, "views_batch": 1, **values})

    monkeypatch.setattr(module, "AdaptSettings", settings)
    return settings


def test_adapt_makes_a_model_that_deblurs_like_a_shipped_one(tmp_path, tiny_checkpoint,
                                                             small_settings, monkeypatch):
    import dualpixel
    from dualpixel.models.checkpoint import read_metadata

    monkeypatch.setattr("dualpixel.adaptation.finetune.MIN_BLURRED_BLOCKS", 4)
    pairs = _pairs(tmp_path / "pairs", with_target=True)
    camera = CAMERA.save(tmp_path / "camera.json")
    out = tmp_path / "adapted"
    args = ["adapt", str(pairs), "--output", str(out), "--checkpoint", str(tiny_checkpoint),
            "--camera", str(camera), *SMALL]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert "held-out frames of the camera" in result.output
    report = json.loads((out / "report.json").read_text())
    assert report["pairs"] == 3 and {r["method"] for r in report["target_free"]} == {
        "start", "adapted"}
    for label in ("start", "adapted"):
        assert np.isfinite(report[label]["camera_val_psnr"])
        assert report[label]["formation_residual"] > 0
    history = [json.loads(line) for line in (out / "train" / "history.jsonl").read_text()
               .splitlines()]
    assert len(history) == 2 and all("formation" in r for r in history)
    meta = read_metadata(out / "adapted.safetensors")["extra"]
    assert meta["adapted_from"]["name"] == str(tiny_checkpoint)
    assert meta["camera"]["disparity_ratio"] == list(CAMERA.disparity_ratio)
    # loads and deblurs as any checkpoint does
    left = np.zeros((64, 96, 3), np.float32) + 0.5
    output = dualpixel.deblur(left, left, model=str(out / "adapted.safetensors"), device="cpu")
    assert output.shape == left.shape
    # a rerun finds everything done and changes nothing; other settings are refused
    before = (out / "adapted.safetensors").read_bytes()
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 0, again.output
    assert (out / "adapted.safetensors").read_bytes() == before
    other = CliRunner().invoke(cli, [*args, "--seed", "5"])
    assert other.exit_code != 0 and "other settings (seed)" in other.output
    assert "Traceback" not in other.output


def test_adapt_refuses_too_few_pairs_and_pairs_it_cannot_measure(tmp_path, tiny_checkpoint,
                                                                   small_settings):
    one = _pairs(tmp_path / "one", count=1)
    result = CliRunner().invoke(cli, ["adapt", str(one), "-o", str(tmp_path / "a"),
                                      "--checkpoint", str(tiny_checkpoint), *SMALL])
    assert result.exit_code != 0 and "holds 1 DP pair(s); adapt needs at least 2" in \
        result.output
    three = _pairs(tmp_path / "three")
    from dualpixel.adaptation.finetune import read_views

    chosen = read_views(three, ("pair[02]", "other*"))
    assert [Path(p[0]).parent.name for p in chosen] == ["pair0", "pair2"]
    result = CliRunner().invoke(cli, ["adapt", str(three), "-o", str(tmp_path / "d"), "--select",
                                      "pair1", "--checkpoint", str(tiny_checkpoint), *SMALL])
    assert result.exit_code != 0 and "holds 1 DP pair(s) matching pair1" in result.output
    flat = tmp_path / "flat"
    for n in range(2):
        (flat / f"p{n}").mkdir(parents=True)
        for view in ("left", "right"):
            write_png(flat / f"p{n}" / f"{view}.png", np.full((160, 224, 3), 0.4), bit_depth=8)
    camera = CAMERA.save(tmp_path / "camera.json")
    result = CliRunner().invoke(cli, ["adapt", str(flat), "-o", str(tmp_path / "b"),
                                      "--checkpoint", str(tiny_checkpoint), "--camera", str(camera),
                                      *SMALL])
    assert result.exit_code != 0, result.output
    assert "too few blurred blocks" in result.output and "p0 0" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "b" / "adapted.safetensors").exists()


def test_adapt_refuses_a_camera_its_views_do_not_measure(tmp_path, tiny_checkpoint,
                                                         small_settings):
    """Views whose disparity ratio the identity cannot tell from their blur (0.45 with our own
    kernels) stop the run before any training, asking for --camera."""
    import cv2

    from dualpixel.calibration.camera import view_kernels
    from tests.calibration.test_camera import TRUE_PSF

    root = tmp_path / "pairs"
    for n in range(3):
        sharp = _texture(224, 224, n)
        k_left, k_right = view_kernels(3.0 + n, TRUE_PSF)
        own, other = (cv2.filter2D(sharp, -1, k, borderType=cv2.BORDER_REFLECT)
                      for k in (k_left, k_right))
        (root / f"p{n}").mkdir(parents=True)
        for name, view in (("left", 0.725 * own + 0.275 * other),
                           ("right", 0.725 * other + 0.275 * own)):
            write_png(root / f"p{n}" / f"{name}.png", np.clip(view, 0, 1), bit_depth=16)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["adapt", str(root), "-o", str(out), "--checkpoint",
                                      str(tiny_checkpoint), *SMALL])
    assert result.exit_code != 0, result.output
    assert "the views do not measure this camera" in result.output
    assert "give --camera" in result.output and "Traceback" not in result.output
    assert not (out / "train").exists() and not (out / "camera.json").exists()


def test_adapt_codes_both_training_sources_and_keeps_its_held_out_frames_clean(tmp_path):
    """``view_coding``: the camera's and the family's synthetic pairs coded as the start's own
    training pairs were; the held-out frames scored before and after stay clean."""
    from dualpixel.adaptation.finetune import AdaptSettings, _data
    from dualpixel.synthesis.on_the_fly import ON_THE_FLY_FILE

    settings = AdaptSettings(scenes=2, scene_size=(128, 96), view_coding="h264:0.25")
    sources, val = _data(tmp_path, settings, CAMERA, grey=False, progress=False)
    for source in sources:
        config = json.loads((Path(source) / ON_THE_FLY_FILE).read_text())["config"]
        assert config["view_coding"]["codec"] == "h264"
        assert config["view_coding"]["share"] == 0.25
    held_out = json.loads((Path(val) / "dataset.json").read_text())
    assert "view_coding" not in held_out["config"]
    clean = AdaptSettings(scenes=2, scene_size=(128, 96))
    sources, _ = _data(tmp_path / "clean", clean, CAMERA, grey=False, progress=False)
    config = json.loads((Path(sources[0]) / ON_THE_FLY_FILE).read_text())["config"]
    assert "view_coding" not in config


def test_adapt_refuses_a_coding_it_cannot_make_before_any_work(tmp_path, tiny_checkpoint,
                                                               monkeypatch):
    from dualpixel.adaptation.finetune import AdaptSettings
    from dualpixel.errors import ParameterError

    pairs = _pairs(tmp_path / "pairs", count=2)
    result = CliRunner().invoke(cli, ["adapt", str(pairs), "-o", str(tmp_path / "a"),
                                      "--checkpoint", str(tiny_checkpoint), "--view-coding",
                                      "gif", *SMALL])
    assert result.exit_code != 0 and "codec must be one of h264, jpeg" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "a").exists()
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "av" else real(name, *a))
    with pytest.raises(ParameterError, match="needs PyAV"):
        AdaptSettings(view_coding="h264")
    assert AdaptSettings(view_coding="jpeg:0.5").coding().share == 0.5  # OpenCV: always there


def test_the_report_tells_apart_pairs_whose_folders_share_a_name():
    from dualpixel.adaptation.report import _pair_names

    pairs = [("dev/scene_00/left.png",), ("dev-hd/scene_00/left.png",),
             ("dev-hd/scene_01/left.png",)]
    assert _pair_names(pairs) == ["dev/scene_00", "dev-hd/scene_00", "scene_01"]
