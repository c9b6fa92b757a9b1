"""Camera calibration from real DP pairs (dualpixel.calibration.camera) and view crosstalk."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel.calibration.camera import DPCamera, calibrate_camera, load_camera
from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.optics.crosstalk import apply_crosstalk
from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.optics.thin_lens import ThinLens
from dualpixel.synthesis.frame import SequenceDraw, synthesize_frame

ROOT_CAMERAS = Path(__file__).resolve().parents[2] / "src" / "dualpixel" / "cameras"
TRUE_PSF = PSFParams(n=3, alpha=0.45, beta=0.2, kappa=0.21)
OTHER_PSF = PSFParams(n=9, alpha=1.0, beta=0.4, kappa=0.14)
RATIO = (0.6, 0.85, 0.75)


def _texture(height: int, width: int, seed: int) -> np.ndarray:
    """Colour texture with edges at every scale (rectangles over smoothed noise)."""
    rng = np.random.default_rng(seed)
    image = cv2.GaussianBlur(rng.random((height, width, 3)).astype(np.float32), (0, 0), 1.0)
    for _ in range(120):
        x0, y0 = rng.integers(0, width), rng.integers(0, height)
        w, h = rng.integers(4, 40, size=2)
        image[y0:y0 + h, x0:x0 + w] = rng.random(3)
    return np.clip(image, 0.0, 1.0)


def _pair(seed: int, ratio=RATIO, params=TRUE_PSF, size=(192, 288), light="encoded",
          falloff=0.0, flat=False):
    """A rendered DP pair of a slanted plane (CoC from -6 to +8 px across the frame), or of a
    plane blurred alike everywhere (``flat``)."""
    height, width = size
    target = _texture(height, width, seed)
    depth = np.tile(np.linspace(1.3, 8.0, width, dtype=np.float32), (height, 1))
    if flat:
        depth = np.full_like(depth, 4.0)
    lens = ThinLens(0.05, 2.0, 2.0, pixel_pitch=1.0)
    camera = ThinLens(0.05, 2.0, 2.0, pixel_pitch=lens.coc_scale / 10.0,
                      max_coc_radius=9.0)
    draw = SequenceDraw(lens=camera, psf=params, distortion=None, noise_sigma=None,
                            disparity_ratio=ratio, light=light, disparity_falloff=falloff)
    frame = synthesize_frame(target, depth, draw)
    hwc = [t.permute(1, 2, 0).numpy() for t in (frame.left, frame.right, frame.target)]
    return (f"pair{seed}", *hwc)


def _centroid_x(kernel: torch.Tensor) -> float:
    x = torch.arange(kernel.shape[-1], dtype=kernel.dtype) - kernel.shape[-1] // 2
    return float((kernel.sum(0) * x).sum() / kernel.sum())


@pytest.mark.parametrize("ratio", [0.0, 0.4, 1.0, 1.3])
def test_crosstalk_scales_the_disparity_and_keeps_the_sum(ratio):
    kernels = dp_psf(7.0, TRUE_PSF)
    left, right = (k[None].expand(3, -1, -1) for k in (kernels.left, kernels.right))
    mixed_left, mixed_right = apply_crosstalk(left, right, (ratio,) * 3)
    before = _centroid_x(kernels.right) - _centroid_x(kernels.left)
    after = _centroid_x(mixed_right[1]) - _centroid_x(mixed_left[1])
    assert after == pytest.approx(ratio * before, abs=1e-5)
    torch.testing.assert_close(mixed_left + mixed_right, left + right)


def test_a_disparity_falloff_narrows_the_views_towards_the_sides():
    """The ratio is ``a (1 - f x^2) / (1 - f / 3)`` across the frame (x -1 to 1): largest in the
    middle, its mean over the width ``a``; a window's columns take the frame's values there."""
    from dualpixel.optics.crosstalk import field_ratio

    kernels = dp_psf(7.0, TRUE_PSF)
    size = kernels.left.shape[-1]
    before = _centroid_x(kernels.right) - _centroid_x(kernels.left)
    width = 9 * size  # nine copies of the kernel pair side by side: one per place in the frame
    left, right = (k.repeat(1, 9)[None].expand(3, -1, -1) for k in (kernels.left, kernels.right))
    mixed_left, mixed_right = apply_crosstalk(left, right, (0.8,) * 3, falloff=0.45)
    torch.testing.assert_close(mixed_left + mixed_right, left + right)
    separations = [(_centroid_x(mixed_right[1][:, i * size:(i + 1) * size])
                    - _centroid_x(mixed_left[1][:, i * size:(i + 1) * size])) / before
                   for i in range(9)]
    assert separations[4] == pytest.approx(max(separations))  # the middle keeps the most
    assert separations[0] == pytest.approx(separations[8], rel=1e-3)
    assert separations[0] < 0.75 * separations[4]
    ratio = field_ratio((0.8,) * 3, 0.45, width)
    assert float(ratio.mean()) == pytest.approx(0.8, rel=1e-3)
    part = field_ratio((0.8,) * 3, 0.45, 20, first_column=33, frame_width=width)
    torch.testing.assert_close(part, ratio[..., 33:53])
    with pytest.raises(ParameterError, match="disparity_falloff"):
        apply_crosstalk(left, right, (0.8,) * 3, falloff=0.95)


def test_crosstalk_refuses_bad_ratios():
    views = torch.zeros(3, 4, 4)
    with pytest.raises(ParameterError, match="one value per channel"):
        apply_crosstalk(views, views, (1.0, 1.0))
    with pytest.raises(ParameterError, match=r"disparity_ratio\[1\] must be finite"):
        apply_crosstalk(views, views, (1.0, float("nan"), 1.0))
    with pytest.raises(ParameterError, match=r"\[0, 1.5\]"):
        apply_crosstalk(views, views, (1.0, 1.6, 1.0))
    with pytest.raises(ParameterError, match=r"disparity_ratio\[2\] must be a number, got True"):
        apply_crosstalk(views, views, (1.0, 1.0, True))


def test_calibration_recovers_known_ratios_and_psf_shape():
    frames = [_pair(seed) for seed in (1, 2)]
    result = calibrate_camera(frames, psf_candidates=(OTHER_PSF, TRUE_PSF), patch=32,
                              max_radius=10.0)
    camera = result.camera
    np.testing.assert_allclose(camera.disparity_ratio, RATIO, atol=0.05)
    assert camera.psf == TRUE_PSF
    assert camera.blocks >= 40 and camera.width == 288
    # the shape matters: the wrong one explains the pairs worse
    scores = dict((p, s) for p, s in result.scores)
    assert scores[TRUE_PSF] < scores[OTHER_PSF]


@pytest.mark.parametrize("falloff", [0.0, 0.5])
def test_calibration_measures_the_disparity_falloff_when_asked(falloff):
    frames = [_pair(seed, ratio=(0.9, 0.9, 0.9), falloff=falloff, flat=True) for seed in (1, 2)]
    camera = calibrate_camera(frames, patch=32, max_radius=10.0, falloff=True).camera
    assert camera.disparity_falloff == pytest.approx(falloff, abs=0.12)
    np.testing.assert_allclose(camera.disparity_ratio, (0.9,) * 3, atol=0.08)
    assert calibrate_camera(frames, patch=32, max_radius=10.0).camera.disparity_falloff == 0.0


@pytest.mark.parametrize("light", ["encoded", "linear"])
def test_calibration_tells_where_the_blur_happens(light):
    """Pairs blurred in linear light (as a lens does) or in the stored values (the paper's
    generator): the calibration says which, and measures the ratios in that space."""
    result = calibrate_camera([_pair(seed, light=light) for seed in (10, 11)], patch=32,
                              max_radius=10.0, psf_candidates=(TRUE_PSF,))
    assert result.camera.light == light
    assert (result.linear_share > 0.7) if light == "linear" else (result.linear_share < 0.3)
    np.testing.assert_allclose(result.camera.disparity_ratio, RATIO, atol=0.05)


def test_calibration_tells_the_paper_model_from_a_real_camera():
    paper = calibrate_camera([_pair(3, ratio=(1.0, 1.0, 1.0))], patch=32, max_radius=10.0,
                             psf_candidates=(TRUE_PSF,))
    np.testing.assert_allclose(paper.camera.disparity_ratio, 1.0, atol=0.05)


def test_calibration_refuses_misaligned_and_textureless_pairs():
    name, left, right, target = _pair(4)
    shifted = np.roll(target, 3, axis=0)
    with pytest.raises(InputFileError, match=r"pair4.*shifted"):
        calibrate_camera([(name, left, right, shifted)], patch=32, max_radius=10.0)
    with pytest.warns(UserWarning, match="left out"), pytest.raises(ParameterError,
                                                                      match="misaligned"):
        calibrate_camera([(name, left, right, shifted)], patch=32, max_radius=10.0,
                         skip_misaligned=True)
    flat = np.full_like(target, 0.5)
    with pytest.raises(ParameterError, match="too few usable blocks"):
        calibrate_camera([("flat", flat, flat, flat)], patch=32, max_radius=10.0)


def test_camera_file_round_trip_and_bad_fields(tmp_path):
    camera = DPCamera("test", 840, (0.7, 0.95, 1.0), TRUE_PSF, noise_std=0.01)
    path = camera.save(tmp_path / "camera.json")
    assert load_camera(path) == camera
    assert "light" not in json.loads(path.read_text())  # files from before it read the same
    assert "disparity_falloff" not in json.loads(path.read_text())
    linear = DPCamera("test", 840, (0.7, 0.95, 1.0), TRUE_PSF, light="linear",
                      disparity_falloff=0.3)
    assert load_camera(linear.save(tmp_path / "linear.json")) == linear
    data = json.loads(path.read_text())
    for change, message in (({"disparity_ratio": [1.0, 1.0]}, "one value per channel"),
                            ({"light": "log"}, "light must be one of encoded, linear"),
                            ({"psf": {"n": 3}}, "psf must hold"),
                            ({"disparity_falloff": 1.2}, "disparity_falloff must be"),
                            ({"colour": 1}, "unknown camera field.*colour"),
                            ({"format": "x"}, "not a dualpixel camera file")):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps({**data, **change}))
        with pytest.raises(InputFileError, match=message):
            load_camera(bad)
    missing = {k: v for k, v in data.items() if k != "width"}
    (tmp_path / "missing.json").write_text(json.dumps(missing))
    with pytest.raises(InputFileError, match="missing: width"):
        load_camera(tmp_path / "missing.json")


def _write_scene(folder, left, right, target):
    folder.mkdir(parents=True)
    for name, image in (("view0", left), ("view1", right), ("target", target)):
        cv2.imwrite(str(folder / f"{name}.png"),
                    np.round(image[..., ::-1] * 255).astype(np.uint8))


def test_calibrate_camera_command_and_synth_with_its_camera(tmp_path):
    for seed in (5, 6):
        _write_scene(tmp_path / "real" / f"scene_{seed}", *_pair(seed)[1:])
    out = tmp_path / "camera.json"
    result = CliRunner().invoke(cli, ["-q", "calibrate", "camera", "--input",
                                      str(tmp_path / "real"), "--output", str(out),
                                      "--patch", "32", "--max-radius", "10",
                                      "--figure", str(tmp_path / "camera.png")])
    assert result.exit_code == 0, result.output
    camera = load_camera(out)
    np.testing.assert_allclose(camera.disparity_ratio, RATIO, atol=0.06)  # 8-bit files
    assert (tmp_path / "camera.png").stat().st_size > 10_000
    # synth --camera: the views carry the camera's ratio, recorded in the dataset
    scenes = tmp_path / "scenes"
    assert CliRunner().invoke(cli, ["-q", "scenes", "--output", str(scenes), "--sequences", "1",
                                    "--frames", "1", "--size", "96x64"]).exit_code == 0
    data = tmp_path / "data"
    result = CliRunner().invoke(cli, ["-q", "synth", "--input", str(scenes), "--output",
                                      str(data), "--lens-sets", "set1", "--camera", str(out),
                                      "--no-noise", "--no-distortion"])
    assert result.exit_code == 0, result.output
    description = json.loads((data / "dataset.json").read_text())
    assert description["config"]["camera"]["disparity_ratio"] == list(camera.to_dict()[
        "disparity_ratio"])
    record = json.loads((data / "manifest.jsonl").read_text().splitlines()[0])
    assert record["disparity_ratio"] == list(camera.disparity_ratio)
    assert record["psf"] == camera.psf.as_dict()


def test_calibrate_and_synth_refuse_bad_input(tmp_path):
    (tmp_path / "nothing").mkdir()
    _name, left, right, target = _pair(7)
    _write_scene(tmp_path / "real" / "scene_a", left, right, np.roll(target, 4, axis=1))
    runner = CliRunner()
    result = runner.invoke(cli, ["calibrate", "camera", "--input", str(tmp_path / "real"),
                                 "--output", str(tmp_path / "c.json"), "--patch", "32"])
    assert result.exit_code == 1 and "scene_a" in result.output and "shifted" in result.output
    assert "Traceback" not in result.output
    result = runner.invoke(cli, ["calibrate", "camera", "--input", str(tmp_path / "real"),
                                 "--output", str(tmp_path / "c.json"), "--falloff",
                                 "--ignore-targets"])
    assert result.exit_code == 2 and "--falloff needs pairs with targets" in result.output
    assert not (tmp_path / "c.json").exists()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "dualpixel-camera-1", "name": "x"}))
    result = runner.invoke(cli, ["synth", "--input", str(tmp_path / "nothing"), "--output",
                                 str(tmp_path / "d"), "--camera", str(bad)])
    assert result.exit_code == 1 and "bad.json" in result.output
    assert "missing: width, disparity_ratio, psf" in result.output


def test_stats_reports_the_disparity_ratio_per_channel(tmp_path):
    for seed in (8, 9):
        _write_scene(tmp_path / "pairs" / f"scene_{seed}", *_pair(seed)[1:])
    result = CliRunner().invoke(cli, ["-q", "stats", str(tmp_path / "pairs"), "--patch", "32",
                                      "--disparity-ratio", "10", "--json",
                                      str(tmp_path / "s.json")])
    assert result.exit_code == 0, result.output
    assert "disparity ratio R/G/B" in result.output
    (summary,) = json.loads((tmp_path / "s.json").read_text())
    np.testing.assert_allclose(summary["disparity_ratio"], RATIO, atol=0.06)


def test_shipped_cameras_load_by_name_and_an_unknown_name_lists_them():
    from dualpixel.cameras import camera_names
    from dualpixel.errors import InputFileError

    assert {"canon-840", "canon-840-linear", "canon-hd", "canon-hd-linear",
            "pixel4"} <= set(camera_names())
    assert load_camera("canon-840-linear").light == "linear"
    with pytest.raises(InputFileError, match="the shipped cameras: canon-840"):
        load_camera("canon-9000")


def test_the_shipped_canon_camera_is_what_calibrate_camera_measures(shared_dir, tmp_path):
    """Issue #76: `canon-840-linear.json` re-derived from the dev Canon pairs at 840x512 with
    the command's defaults: the same blocks, blur sizes and light, the disparity ratios to the
    file's last digit but one, the noise to 1 %."""
    shipped = json.loads((ROOT_CAMERAS / "canon-840-linear.json").read_text())
    out = tmp_path / "camera.json"
    result = CliRunner().invoke(cli, ["-q", "calibrate", "camera", "--input",
                                      str(shared_dir / "data" / "canon-dp-real"), "-o", str(out),
                                      "--name", "canon-840-linear"])
    assert result.exit_code == 0, result.output
    measured = json.loads(out.read_text())
    for key in ("format", "name", "width", "psf", "coc_percentiles", "blocks", "light"):
        assert measured[key] == shipped[key], key
    assert measured["disparity_ratio"] == pytest.approx(shipped["disparity_ratio"], abs=1e-3)
    assert measured["noise_std"] == pytest.approx(shipped["noise_std"], rel=0.01)
