"""Lossy coding of stored DP views: H.264 of the pair, JPEG of each view, in written and
on-the-fly data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.data.dataset import PatchConfig
from dualpixel.errors import ParameterError
from dualpixel.io.images import read_rgb
from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
from dualpixel.synthesis.on_the_fly import OnTheFlyDataset, write_on_the_fly
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder
from dualpixel.synthesis.view_coding import (
    ViewCoding,
    code_views,
    h264_round_trip,
    jpeg_round_trip,
)

SETTINGS = dict(lens_sets=("dslr-840",), psf_bank="pixel4", noise_model="poisson-gaussian",
                noise_sigmas=(0.006,), bit_depth=8, distortion=False, seed=3)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / np.mean((a.astype(float) - b.astype(float)) ** 2)))


def _pair(height: int = 64, width: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """Two smooth 8-bit views, the right one shifted by 2 px."""
    y, x = np.mgrid[:height, : width + 2]
    image = 128 + 60 * np.sin(x / 5.0)[..., None] * np.cos(y / 7.0)[..., None] \
        + np.array([0, 20, -20])
    image = np.clip(image, 0, 255).astype(np.uint8)
    return image[:, :width], image[:, 2:]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("coding") / "scenes"
    write_scene_folder(root, 2, SceneConfig(width=96, height=64, frames=1, layout="photo"),
                       seed=4, progress=False)
    return root


def test_h264_round_trip_keeps_the_frames_close_and_their_size():
    left, right = _pair(63, 95)  # odd sizes: padded for 4:2:0 and cut back
    coded = h264_round_trip(np.stack([left, right]), 18)
    assert coded.shape == (2, 63, 95, 3) and coded.dtype == np.float32
    assert _psnr(left, right) < 30  # so each view comes back as itself, not the other
    assert 38 < _psnr(coded[0], left) < 70 and 38 < _psnr(coded[1], right) < 70
    worse = h264_round_trip(np.stack([left, right]), 40)
    assert _psnr(worse[0], left) < _psnr(coded[0], left)  # a higher CRF loses more
    assert 30 < _psnr(jpeg_round_trip(left, 90), left) < 60


def test_coding_is_drawn_per_frame_from_its_seed():
    left, right = _pair()
    never, always = ViewCoding("jpeg", share=0.0), ViewCoding("jpeg", share=1.0)
    assert code_views(left, right, never, 7)[0] is left
    first, second = code_views(left, right, always, 7), code_views(left, right, always, 7)
    assert np.array_equal(first[0], second[0]) and not np.array_equal(first[0], left)
    coded = [code_views(left, right, ViewCoding("h264", share=0.5), seed)[0] is not left
             for seed in range(40)]
    assert 8 < sum(coded) < 32  # about half the frames
    grey = code_views(left[..., 1], right[..., 1], always, 7)
    assert grey[0].shape == left.shape[:2] and grey[0].dtype == np.uint8


def test_coding_settings_are_checked_and_recorded():
    config = SynthConfig(bit_depth=8, view_coding={"codec": "jpeg", "share": 0.25})
    assert config.coding() == ViewCoding("jpeg", 0.25, (50, 95))
    assert SynthConfig.from_dict(config.as_dict()) == config
    assert "view_coding" not in SynthConfig(bit_depth=8).as_dict()  # older files stay as they are
    for bad, message in [
        (dict(bit_depth=16, view_coding={"codec": "h264"}), "8-bit display-encoded"),
        (dict(bit_depth=8, view_coding={"codec": "gif"}), "codec must be one of h264, jpeg"),
        (dict(bit_depth=8, view_coding={"codec": "h264", "quality": [30, 18]}), "quality"),
        (dict(bit_depth=8, view_coding={"codec": "h264", "crf": 23}), "unknown view_coding"),
        (dict(bit_depth=8, view_coding={"codec": "h264", "share": 1.5}), "share"),
        (dict(bit_depth=8, view_coding={"codec": "h264", "share": "half"}), "share must be"),
        (dict(bit_depth=8, view_coding={"codec": "jpeg", "quality": 90}), "quality for jpeg"),
    ]:
        with pytest.raises(ParameterError, match=message):
            SynthConfig(**bad)


def test_written_and_on_the_fly_views_are_coded_and_targets_kept(scenes, tmp_path):
    coded_settings = {**SETTINGS, "view_coding": {"codec": "h264", "share": 1.0}}
    plain, coded = tmp_path / "plain", tmp_path / "coded"
    synthesize_dataset(scenes, "rgbd", plain, SynthConfig(**SETTINGS), progress=False)
    synthesize_dataset(scenes, "rgbd", coded, SynthConfig(**coded_settings), progress=False)
    frame = "seq_001/frame_0000.png"
    clean, views = {}, {}
    for name, folder in (("left", "train_l/source"), ("right", "train_r/source"),
                         ("combined", "train_c/source"), ("target", "train_c/target")):
        clean[name] = read_rgb(plain / folder / frame)
        views[name] = read_rgb(coded / folder / frame)
    np.testing.assert_array_equal(clean["target"], views["target"])
    for name in ("left", "right"):  # (tiny saturated frames: 4:2:0 costs them much colour)
        assert 15 < _psnr(clean[name] * 255, views[name] * 255) < 60, name
    mean = (views["left"] + views["right"]) / 2
    assert np.abs(mean - views["combined"]).max() <= 0.5 / 255 + 1e-6
    # on the fly: each crop coded as it is drawn, the target clean
    sources = {}
    for name, settings in (("plain", SETTINGS), ("coded", coded_settings)):
        write_on_the_fly(tmp_path / f"fly-{name}", scenes, "rgbd", SynthConfig(**settings))
        sources[name] = OnTheFlyDataset(tmp_path / f"fly-{name}",
                                        PatchConfig(patch_size=32, flips=False))
    a, b = sources["plain"][(0, 9)], sources["coded"][(0, 9)]
    assert np.array_equal(a["target"].numpy(), b["target"].numpy())
    assert not np.array_equal(a["left"].numpy(), b["left"].numpy())


def test_synth_command_takes_a_codec_and_refuses_bad_ones(scenes, tmp_path):
    runner = CliRunner()
    base = ["synth", "--input", str(scenes), "--lens-sets", "set1", "--layers", "40"]
    result = runner.invoke(cli, [*base, "--output", str(tmp_path / "ok"), "--bit-depth", "8",
                                 "--view-coding", "jpeg:1"])
    assert result.exit_code == 0, result.output
    for options, message in [
        (["--bit-depth", "8", "--view-coding", "gif"], "codec must be one of h264, jpeg"),
        (["--bit-depth", "8", "--view-coding", "h264:half"], "expected CODEC or CODEC:SHARE"),
        (["--view-coding", "h264"], "8-bit display-encoded views"),
    ]:
        bad = runner.invoke(cli, [*base, "--output", str(tmp_path / "bad"), *options])
        assert bad.exit_code == 2 and "Traceback" not in bad.output, bad.output
        assert message in bad.output
        assert not (tmp_path / "bad").exists()


def test_h264_coding_without_pyav_is_refused_before_any_frame(scenes, tmp_path, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "av" else real(name, *a))
    bad = CliRunner().invoke(cli, ["synth", "--input", str(scenes), "--lens-sets", "set1",
                                   "--output", str(tmp_path / "bad"), "--bit-depth", "8",
                                   "--view-coding", "h264"])
    assert bad.exit_code == 2 and "needs PyAV: pip install av" in bad.output, bad.output
    assert "Traceback" not in bad.output and not (tmp_path / "bad").exists()


def _recipe_coding_views(folder: Path, source: str) -> Path:
    import yaml

    raw = {"name": "coded", "description": "coded views",
           "data": [{"name": "scenes", "scenes": {"sequences": 1, "frames": 1, "width": 96,
                                                   "height": 64, "seed": 1}},
                    {"name": "synth", "synth": {"input": "scenes", "lens_sets": ["set1"],
                                                "bit_depth": 8, "source": source,
                                                "view_coding": {"codec": "h264"}}}],
           "train": {"model": "rdpd", "synthetic_data": "synth", "epochs": 1,
                     "iterations_per_epoch": 1, "patch_size": 32},
           "phases": [{"name": "only"}]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "coded.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    return folder / "coded.yaml"


@pytest.mark.parametrize("source", ["written", "on-the-fly"])
def test_a_recipe_coding_views_without_pyav_is_refused_before_its_run(tmp_path, monkeypatch,
                                                                       source):
    import importlib.util

    from dualpixel.errors import InputFileError
    from dualpixel.training.recipe import check_codecs, load_recipe

    path = _recipe_coding_views(tmp_path, source)
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "av" else real(name, *a))
    for extra in ([], ["--dry-run"]):
        bad = CliRunner().invoke(cli, ["reproduce", str(path), "--output", str(tmp_path / "run"),
                                       *extra])
        assert bad.exit_code == 1 and "Traceback" not in bad.output, bad.output  # the recipe's
        assert "data step synth" in bad.output and "needs PyAV" in bad.output, bad.output
        assert not (tmp_path / "run").exists()
    # written views already coded need no codec to train on; on-the-fly ones code as they train
    done = tmp_path / "run/data/synth"
    done.mkdir(parents=True)
    (done / "dataset.json").write_text('{"status": "complete"}')
    recipe = load_recipe(path)
    if source == "written":
        check_codecs(recipe, tmp_path / "run")
    else:
        with pytest.raises(InputFileError, match="needs PyAV"):
            check_codecs(recipe, tmp_path / "run")
