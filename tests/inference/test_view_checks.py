"""Input checks name the likely mistake: views swapped, at half brightness, from two captures."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import dualpixel
from dualpixel.cli.main import cli
from dualpixel.io.images import read_rgb, write_png


@pytest.fixture(scope="module")
def frame(behind_focus_frame):
    return behind_focus_frame


def codes(findings) -> list[str]:
    return [f.code for f in findings]


def test_synthetic_pair_passes_and_swapped_is_named(frame):
    left, right, combined = frame["left"], frame["right"], frame["combined"]
    assert codes(dualpixel.check_views(left, right, combined)) == []
    swapped = dualpixel.check_views(right, left, combined)
    assert codes(swapped) == ["swapped"] and "left" in swapped[0].message


def test_half_brightness_and_other_captures(frame):
    left, right, combined = frame["left"], frame["right"], frame["combined"]
    half = dualpixel.check_views(left / 2, right / 2, combined)
    assert codes(half) == ["half-bright"] and "--views-sum" in half[0].message
    assert codes(dualpixel.check_views(left / 2, right / 2)) == ["half-bright"]
    assert codes(dualpixel.check_views(left * 0.7, right * 0.7, combined)) == ["brightness"]
    other = np.ascontiguousarray(combined[:, ::-1])
    assert codes(dualpixel.check_views(left, right, other)) == ["not-combined"]
    assert "unbalanced" in codes(dualpixel.check_views(left, right * 0.5))


def test_real_canon_pairs(shared_dir):
    scene = shared_dir / "data" / "canon-dp-real-hd" / "scene_03"
    left, right = read_rgb(scene / "view0.png"), read_rgb(scene / "view1.png")
    combined = read_rgb(scene / "input.png")
    assert codes(dualpixel.check_views(left, right, combined)) == []
    assert codes(dualpixel.check_views(right, left, combined)) == ["swapped"]


def test_deblur_warns_on_a_canon_scene_and_strict_stops(shared_dir, tiny_checkpoint, tmp_path):
    scene = shared_dir / "data" / "canon-dp-real" / "scene_01"
    for name in ("view0", "view1"):  # a raw A/B split's views: half the light each
        write_png(tmp_path / f"{name}-half.png", read_rgb(scene / f"{name}.png") / 2, bit_depth=16)
    cases = {
        "swapped": ["--left", scene / "view1.png", "--right", scene / "view0.png"],
        "--views-sum": ["--left", tmp_path / "view0-half.png", "--right",
                           tmp_path / "view1-half.png", "--combined", scene / "input.png"],
    }
    runner = CliRunner()
    for words, views in cases.items():
        args = ["deblur", *views, "--checkpoint", tiny_checkpoint, "--device", "cpu"]
        warned = runner.invoke(cli, [str(a) for a in [*args, "-o", tmp_path / "w.png"]])
        assert warned.exit_code == 0 and "Warning:" in warned.output and words in warned.output
        strict = runner.invoke(cli, [str(a) for a in [*args, "-o", tmp_path / "s.png",
                                                      "--strict"]])
        assert strict.exit_code == 1 and words in strict.output, strict.output
        assert not (tmp_path / "s.png").exists() and "Traceback" not in strict.output


def test_views_sum_doubles_and_strict_stops(frame, tiny_checkpoint, tmp_path):
    for name in ("left", "right", "combined"):
        image = frame[name] / (2 if name != "combined" else 1)
        write_png(tmp_path / f"{name}.png", image, bit_depth=16)
    args = ["deblur", "--left", str(tmp_path / "left.png"), "--right",
            str(tmp_path / "right.png"), "--combined", str(tmp_path / "combined.png"),
            "--checkpoint", str(tiny_checkpoint), "--device", "cpu"]
    runner = CliRunner()
    warned = runner.invoke(cli, [*args, "-o", str(tmp_path / "a.png")])
    assert warned.exit_code == 0 and "Warning:" in warned.output and "--views-sum" in warned.output
    strict = runner.invoke(cli, [*args, "-o", str(tmp_path / "b.png"), "--strict"])
    assert strict.exit_code == 1 and "--strict" in strict.output
    assert not (tmp_path / "b.png").exists() and "Traceback" not in strict.output
    fixed = runner.invoke(cli, [*args, "-o", str(tmp_path / "c.png"), "--views-sum", "--strict"])
    assert fixed.exit_code == 0 and "Warning:" not in fixed.output
    api = dualpixel.deblur(frame["left"] / 2, frame["right"] / 2, views_sum=True,
                           model=str(tiny_checkpoint), device="cpu",
                           precision="fp32")
    direct = dualpixel.deblur(np.clip(frame["left"], 0, 1), np.clip(frame["right"], 0, 1),
                              model=str(tiny_checkpoint), device="cpu",
                              precision="fp32")
    assert np.abs(api - direct).max() < 1e-5


def test_block_coded_views_are_named():
    """A synthetic pair of smooth surfaces passes; the same views through JPEG at quality 80
    (8-px blocks, whatever the grid's offset) are named."""
    import cv2

    def jpeg(image, offset=0):
        stored = np.round(image[offset:, offset:] * 255).astype(np.uint8)
        data = cv2.imencode(".jpg", stored, [cv2.IMWRITE_JPEG_QUALITY, 80])[1]
        return cv2.imdecode(data, cv2.IMREAD_UNCHANGED).astype(np.float32) / 255

    rng = np.random.default_rng(4)
    shading = cv2.GaussianBlur(rng.standard_normal((288, 320, 3)).astype(np.float32), (0, 0), 4)
    rgb = np.clip(0.45 + 0.03 * shading / shading.std(), 0.02, 0.9)
    depth = np.where(np.arange(320)[None, :] < 128, 1.0, 3.0).repeat(288, 0).astype(np.float32)
    views = dualpixel.synthesize(rgb, depth, lens_set="dslr-840", noise=False, distortion=False)
    left, right = (np.asarray(views[k], np.float32) for k in ("left", "right"))
    assert "block-coded" not in codes(dualpixel.check_views(left, right))
    for offset in (0, 3):
        found = dualpixel.check_views(jpeg(left, offset), jpeg(right, offset))
        assert codes(found) == ["block-coded"] and "losslessly" in found[0].message


def test_block_coded_real_pairs(shared_dir):
    from dualpixel.inference.view_checks import BLOCK_CODED, blockiness

    pairs = shared_dir / "data" / "dp-real-nogt"
    video = read_rgb(pairs / "pixel-mp4-07" / "left.png")
    still = read_rgb(pairs / "sdirt-box-001" / "left.png")
    assert blockiness(video) > BLOCK_CODED > blockiness(still)
    assert blockiness(still[:255]) is None  # too small to tell


def test_a_dark_photograph_is_not_sent_to_views_sum_without_a_word(shared_dir):
    """Without a combined image, a dark real phone pair (never above half of full scale) reads
    like views that sum to it: the finding names both, so that a user of a dark photograph does
    not double its views."""
    pair = shared_dir / "data" / "dp-real-nogt" / "pixel-gif-04"
    left, right = (read_rgb(pair / f"{side}.png") for side in ("left", "right"))
    found = [f for f in dualpixel.check_views(left, right) if f.code == "half-bright"]
    assert found and "--views-sum" in found[0].message and "just dark" in found[0].message


def test_mixed_bit_depths_are_named(frame, tmp_path):
    from dualpixel.inference.view_checks import check_views

    found = check_views(frame["left"], frame["right"], bit_depths=(16, 8))
    assert codes(found) == ["bit-depth"] and "16-bit" in found[0].message


def test_views_sum_without_a_right_view_is_refused(frame, tmp_path):
    """A single-view model reads only the left view, but --views-sum needs both to be doubled:
    refused before any output, not silently ignored."""
    import torch

    from dualpixel.models import build_model, save_model

    torch.manual_seed(0)
    save_model(tmp_path / "single.safetensors", build_model("rspd", width=0.125))
    write_png(tmp_path / "left.png", frame["left"] / 2, bit_depth=16)
    write_png(tmp_path / "right.png", frame["right"] / 2, bit_depth=16)
    args = ["deblur", "--left", str(tmp_path / "left.png"), "--checkpoint",
            str(tmp_path / "single.safetensors"), "--device", "cpu", "--views-sum"]
    refused = CliRunner().invoke(cli, [*args, "-o", str(tmp_path / "a.png")])
    assert refused.exit_code == 2 and "--views-sum needs both views" in refused.output
    assert not (tmp_path / "a.png").exists() and "Traceback" not in refused.output
    done = CliRunner().invoke(cli, [*args, "--right", str(tmp_path / "right.png"),
                                    "-o", str(tmp_path / "b.png")])
    assert done.exit_code == 0, done.output
