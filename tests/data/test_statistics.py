"""Dataset statistics: known disparity, blur and noise are measured back; bad input is refused."""

import json

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.data.statistics import (
    block_blur,
    block_disparity,
    dataset_statistics,
    frame_statistics,
    noise_level,
)
from dualpixel.errors import InputFileError, ParameterError


def _texture(height=192, width=256, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.uniform(0, 1, (height // 4, width // 4, 3)).astype(np.float32)
    return cv2.resize(base, (width, height), interpolation=cv2.INTER_CUBIC).clip(0, 1)


@pytest.mark.parametrize("shift", [-3, 0, 2, 5])
def test_disparity_of_a_known_shift(shift):
    left = _texture()
    right = np.roll(left, shift, axis=1)  # R(x) = L(x - shift)
    measured = block_disparity(left, right)
    assert measured.size > 0
    assert np.median(measured) == pytest.approx(shift, abs=0.1)


@pytest.mark.parametrize("sigma", [0.0, 1.0, 2.5])
def test_blur_of_a_known_gaussian(sigma):
    target = _texture(seed=1)
    blurred = target if sigma == 0 else cv2.GaussianBlur(target, (0, 0), sigma)
    measured = block_blur(blurred, target)
    assert np.median(measured) == pytest.approx(sigma, abs=0.25)


def test_noise_level_of_known_noise():
    clean = _texture(seed=2)
    rng = np.random.default_rng(0)
    for std in (0.005, 0.02):
        noisy = clean + rng.normal(0, std, clean.shape).astype(np.float32)
        assert noise_level(noisy) == pytest.approx(std, rel=0.2)


def test_frame_statistics_refuse_mismatched_sizes():
    image = _texture()
    with pytest.raises(ParameterError, match="one size"):
        frame_statistics(image, image[:, :-8])


def test_statistics_of_a_synthetic_dataset(tiny_synthetic_dataset):
    """The dataset's statistics pool those of its frames, each measured alone (issue #76: the
    blur was only checked to be present)."""
    from dualpixel.data.layout import discover_any, read_frame
    from dualpixel.io.images import read_rgb

    stats = dataset_statistics(tiny_synthetic_dataset, split="train", patch=32)
    summary = stats.summary()
    assert stats.frames == 12
    assert json.loads(json.dumps(summary)) == summary
    frames = [f for s in discover_any(tiny_synthetic_dataset, "train") for f in s.frames]
    alone = [frame_statistics(*(read_frame(f)[k] for k in ("left", "right", "target")),
                              read_rgb(f.combined), patch=32) for f in frames]
    np.testing.assert_array_equal(stats.blur, np.concatenate([a.blur for a in alone]))
    np.testing.assert_array_equal(stats.disparity, np.concatenate([a.disparity for a in alone]))
    assert summary["blur_sigma_px"]["p50"] == pytest.approx(
        float(np.percentile(stats.blur, 50)), abs=1e-4)
    assert 0 < summary["blur_sigma_px"]["p90"] <= 8.0  # the synthetic frames are blurred


def test_stats_command_compares_two_datasets(tiny_synthetic_dataset, shared_dir, tmp_path):
    canon = shared_dir / "data" / "canon-dp-real"
    result = CliRunner().invoke(cli, [
        "stats", str(canon), str(tiny_synthetic_dataset), "--split", "train", "--patch", "32",
        "--output", str(tmp_path / "s.png"), "--json", str(tmp_path / "s.json"),
    ])
    # --split applies to DPDD layouts only; scene folders need none
    assert result.exit_code == 0, result.output
    assert "blur std px p50" in result.output
    summaries = json.loads((tmp_path / "s.json").read_text())
    assert [s["name"] for s in summaries] == ["canon-dp-real", tiny_synthetic_dataset.name]
    assert cv2.imread(str(tmp_path / "s.png")) is not None


def test_stats_bad_input_names_the_file(tmp_path):
    scene = tmp_path / "scenes" / "scene_00"
    scene.mkdir(parents=True)
    cv2.imwrite(str(scene / "view0.png"), np.zeros((80, 96, 3), np.uint8))
    cv2.imwrite(str(scene / "view1.png"), np.zeros((80, 96, 3), np.uint8))
    with pytest.raises(InputFileError, match="target image missing"):
        dataset_statistics(tmp_path / "scenes")
    cv2.imwrite(str(scene / "target.png"), np.zeros((64, 96, 3), np.uint8))
    with pytest.raises(InputFileError, match=r"target\.png"):
        dataset_statistics(tmp_path / "scenes")
    result = CliRunner().invoke(cli, ["stats", str(tmp_path / "empty")])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert "empty" in result.output


def test_histogram_bins_grow_to_hold_every_value():
    import numpy as np

    from dualpixel.viz.statistics_figure import _edges

    edges = _edges([np.array([-11.9, 0.0, 3.0]), np.array([10.2])], -8.0, 8.0, 0.25)
    assert edges[0] <= -11.9 and edges[-1] >= 10.2  # nothing piled into the end bins
    np.testing.assert_allclose(np.diff(edges), 0.25)
    assert edges[0] == -12.0 and edges[-1] == 10.25
    np.testing.assert_allclose(_edges([np.array([0.01])], 0.0, 0.04, 0.00125)[[0, -1]],
                               [0.0, 0.04])  # inside the default range: the default bins
