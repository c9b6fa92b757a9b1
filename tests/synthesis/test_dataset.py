import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.atomic import PARTIAL_GLOB
from dualpixel.io.images import decode_synthia_depth, read_synthia_depth
from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder

SMALL = SceneConfig(width=64, height=48, frames=2, leaves=6)
FAST = {"lens_sets": ("set0", "set4"), "max_layers": 40}


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("scenes")
    write_scene_folder(root, 2, SMALL, seed=7, progress=False)
    return root


def tree_bytes(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
        if p.is_file() and p.suffix in (".png", ".npy")
    }


def read16(path: Path) -> np.ndarray:
    data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert data is not None and data.dtype == np.uint16
    return data.astype(np.int64)


def test_layout_manifest_and_combined_is_mean_of_views(scene_dir, tmp_path):
    out = tmp_path / "ds"
    summary = synthesize_dataset(scene_dir, "rgbd", out, SynthConfig(noise=False, **FAST),
                                 progress=False)
    assert summary["status"] == "complete" and summary["frames_done"] == 2 * 2 * 2
    records = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert len(records) == 8
    # seq numbering as the authors': camera-major, 1-based; one camera and PSF per sequence
    assert {r["sequence"] for r in records} == {1, 2, 3, 4}
    by_seq = {}
    for r in records:
        by_seq.setdefault(r["sequence"], set()).add(json.dumps([r["camera"], r["psf"]]))
        for key in ("camera", "psf", "distortion", "noise_sigma", "seed", "version", "input"):
            assert key in r
    assert all(len(v) == 1 for v in by_seq.values())
    assert {r["render_mode"] for r in records} == {"fast"}  # the default renderer, recorded
    for r in records:
        left, right = read16(out / r["outputs"]["left"]), read16(out / r["outputs"]["right"])
        combined = read16(out / r["outputs"]["combined"])
        assert np.abs(2 * combined - (left + right)).max() <= 1
        target = read16(out / r["outputs"]["target"])
        defocus = np.load(out / r["outputs"]["defocus"])
        assert defocus.dtype == np.float32 and defocus.shape == target.shape[:2]
    for folder in ("train_c/source", "train_l/source", "train_r/source", "train_c/target",
                   "train_c/defocus"):
        assert (out / folder / "seq_001").is_dir()


def test_same_seed_gives_bit_identical_files(scene_dir, tmp_path):
    config = SynthConfig(seed=3, **FAST)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "a", config, progress=False)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "b", config, progress=False, workers=2)
    assert tree_bytes(tmp_path / "a") == tree_bytes(tmp_path / "b")
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "c", SynthConfig(seed=4, **FAST),
                       progress=False)
    assert tree_bytes(tmp_path / "a") != tree_bytes(tmp_path / "c")


def test_interrupted_run_resumes_to_the_same_dataset(scene_dir, tmp_path):
    config = SynthConfig(seed=5, **FAST)
    partial = synthesize_dataset(scene_dir, "rgbd", tmp_path / "r", config, progress=False,
                                 limit=3)
    assert partial["status"] == "incomplete" and partial["frames_done"] == 3
    described = json.loads((tmp_path / "r" / "dataset.json").read_text())
    assert described["status"] == "incomplete"
    # a torn manifest line (killed mid-append) is not taken as a finished frame
    with open(tmp_path / "r" / "manifest.jsonl", "a") as handle:
        handle.write('{"key": "train/seq_00')
    done = synthesize_dataset(scene_dir, "rgbd", tmp_path / "r", config, progress=False)
    assert done["status"] == "complete" and done["frames_done"] == 8
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "full", config, progress=False)
    assert tree_bytes(tmp_path / "r") == tree_bytes(tmp_path / "full")
    assert not list((tmp_path / "r").rglob(PARTIAL_GLOB))


def test_output_folder_with_other_configuration_is_refused(scene_dir, tmp_path):
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "d", SynthConfig(**FAST), progress=False,
                       limit=1)
    with pytest.raises(InputFileError, match=r"different configuration \(differs in seed\)"):
        synthesize_dataset(scene_dir, "rgbd", tmp_path / "d", SynthConfig(seed=9, **FAST),
                           progress=False)


def test_folder_moved_with_its_input_resumes(scene_dir, tmp_path):
    """A run folder holding the input and the dataset, moved or copied whole, is the same
    dataset; a dataset whose input changed both ways is refused."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(scene_dir, run / "scenes")
    config = SynthConfig(**FAST)
    synthesize_dataset(run / "scenes", "rgbd", run / "data", config, progress=False, limit=2)
    moved = tmp_path / "elsewhere" / "run-moved"
    moved.parent.mkdir()
    run.rename(moved)
    done = synthesize_dataset(moved / "scenes", "rgbd", moved / "data", config, progress=False)
    assert done["status"] == "complete" and done["frames_done"] == 8
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "full", config, progress=False)
    assert tree_bytes(moved / "data") == tree_bytes(tmp_path / "full")
    other = tmp_path / "other-scenes"
    shutil.copytree(scene_dir, other)
    with pytest.raises(InputFileError, match=r"different configuration \(differs in input\)"):
        synthesize_dataset(other, "rgbd", moved / "data", config, progress=False)


def make_rgbd(root: Path, names=("a", "b"), size=(40, 30)) -> Path:
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    for name in names:
        cv2.imwrite(str(root / "rgb" / f"{name}.png"), np.full((size[1], size[0], 3), 128,
                                                                np.uint8))
        np.save(root / "depth" / f"{name}.npy", np.full((size[1], size[0]), 5.0, np.float32))
    return root


@pytest.mark.parametrize(
    ("breakage", "culprit", "message"),
    [
        ("size", "depth/b.npy", "depth is 20x10 but b.png is 40x30"),
        ("missing", "rgb/b.png", "has no depth map"),
        ("extra", "depth/c.npy", "has no RGB frame"),
        ("nan", "depth/b.npy", "NaN/inf"),
        ("negative", "depth/b.npy", "zero or negative"),
        ("corrupt", "rgb/b.png", "cannot be decoded"),
        ("depth8", "depth/b.png", "must be 16-bit"),
    ],
)
def test_bad_input_names_the_file(tmp_path, breakage, culprit, message):
    root = make_rgbd(tmp_path / "in")
    if breakage == "size":
        np.save(root / "depth" / "b.npy", np.full((10, 20), 5.0, np.float32))
    elif breakage == "missing":
        (root / "depth" / "b.npy").unlink()
    elif breakage == "extra":
        np.save(root / "depth" / "c.npy", np.full((30, 40), 5.0, np.float32))
    elif breakage in ("nan", "negative"):
        depth = np.full((30, 40), 5.0, np.float32)
        depth[3, 4] = np.nan if breakage == "nan" else -1.0
        np.save(root / "depth" / "b.npy", depth)
    elif breakage == "corrupt":
        (root / "rgb" / "b.png").write_bytes(b"\x89PNG\r\n\x1a\nthis is not a png")
    elif breakage == "depth8":
        (root / "depth" / "b.npy").unlink()
        cv2.imwrite(str(root / "depth" / "b.png"), np.full((30, 40), 9, np.uint8))
    with pytest.raises(InputFileError, match=message) as error:
        synthesize_dataset(root, "rgbd", tmp_path / "out", SynthConfig(**FAST), progress=False)
    assert str(error.value).startswith(str(root / culprit))
    status = tmp_path / "out" / "dataset.json"
    assert not status.exists() or json.loads(status.read_text())["status"] == "incomplete"


def test_synthia_depth_decoding_from_an_encoded_png(tmp_path):
    metres = np.array([[0.5, 7.25, 120.0], [249.0, 300.0, 1000.0]])
    code = np.round(metres / 1000.0 * (2**24 - 1)).astype(np.int64)
    bgr = np.stack((code // 65536, (code // 256) % 256, code % 256), axis=-1).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "d.png"), bgr)
    depth = read_synthia_depth(tmp_path / "d.png", max_depth=250.0)
    expected = np.minimum(metres, 250.0)
    np.testing.assert_allclose(depth, expected, atol=1e-4)
    np.testing.assert_allclose(decode_synthia_depth(bgr, max_depth=1000.0), metres, atol=1e-4)


def test_synthia_layout_and_split(tmp_path):
    for seq in ("SEQ1", "SEQ3"):
        for sub in ("RGBLeft", "DepthLeft"):
            (tmp_path / "in" / seq / sub).mkdir(parents=True)
        cv2.imwrite(str(tmp_path / "in" / seq / "RGBLeft" / "0000.png"),
                    np.full((24, 32, 3), 90, np.uint8))
        code = np.full((24, 32), int(20.0 / 1000 * (2**24 - 1)))
        bgr = np.stack((code // 65536, (code // 256) % 256, code % 256), -1).astype(np.uint8)
        cv2.imwrite(str(tmp_path / "in" / seq / "DepthLeft" / "0000.png"), bgr)
    summary = synthesize_dataset(tmp_path / "in", "synthia", tmp_path / "out",
                                 SynthConfig(lens_sets=("set2",)), progress=False)
    assert summary["status"] == "complete"
    assert (tmp_path / "out" / "train_c" / "source" / "seq_001" / "0000.png").is_file()
    assert (tmp_path / "out" / "test_c" / "source" / "seq_002" / "0000.png").is_file()


def test_scenes_then_synth_end_to_end_through_the_cli(tmp_path):
    runner = CliRunner()
    scenes = runner.invoke(cli, ["scenes", "--output", str(tmp_path / "sc"), "--sequences", "1",
                                 "--frames", "3", "--size", "72x40", "--seed", "2"])
    assert scenes.exit_code == 0, scenes.output
    assert len(list((tmp_path / "sc" / "seq_000" / "depth").glob("*.npy"))) == 3
    synth = runner.invoke(cli, ["synth", "--input", str(tmp_path / "sc"), "--output",
                                str(tmp_path / "ds"), "--lens-sets", "set1,set3", "--layers", "64",
                                "--bit-depth", "8"])
    assert synth.exit_code == 0, synth.output
    assert "complete: 6/6 frames" in synth.output
    left = cv2.imread(str(tmp_path / "ds" / "train_l" / "source" / "seq_002" / "frame_0002.png"),
                      cv2.IMREAD_UNCHANGED)
    assert left.dtype == np.uint8 and left.shape == (40, 72, 3)
    bad = runner.invoke(cli, ["synth", "--input", str(tmp_path / "nowhere"), "--output",
                              str(tmp_path / "x")])
    assert bad.exit_code == 1 and "nowhere" in bad.output
    # a dataset written before lens sets had their name, resumed with the old option's name
    description = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    description["config"]["cameras"] = description["config"].pop("lens_sets")
    (tmp_path / "ds" / "dataset.json").write_text(json.dumps(description))
    old = runner.invoke(cli, ["synth", "--input", str(tmp_path / "sc"), "--output",
                              str(tmp_path / "ds"), "--cameras", "set1,set3", "--layers", "64",
                              "--bit-depth", "8"])
    assert old.exit_code == 0, old.output
    assert "Warning: --cameras is now --lens-sets" in old.output
    assert "complete: 6/6 frames" in old.output and "different configuration" not in old.output
    both = runner.invoke(cli, ["synth", "--input", str(tmp_path / "sc"), "--output",
                               str(tmp_path / "ds"), "--cameras", "set1", "--lens-sets", "set1"])
    assert both.exit_code == 2 and "--lens-sets only" in both.output


def test_preview_and_custom_noise_sigmas_through_the_cli(scene_dir, tmp_path):
    runner = CliRunner()
    synth = runner.invoke(cli, ["synth", "--input", str(scene_dir), "--output",
                                str(tmp_path / "ds"), "--lens-sets", "set2", "--layers", "32",
                                "--noise-sigmas", "0.01,0.02"])
    assert synth.exit_code == 0, synth.output
    records = [json.loads(x) for x in (tmp_path / "ds" / "manifest.jsonl").read_text().split("\n")
               if x]
    assert {r["noise_sigma"] for r in records} <= {0.01, 0.02}
    shown = runner.invoke(cli, ["preview", "--dataset", str(tmp_path / "ds"), "--output",
                                str(tmp_path / "p.png")])
    assert shown.exit_code == 0, shown.output
    image = cv2.imread(str(tmp_path / "p.png"))
    assert image is not None and image.shape[1] > 800
    (tmp_path / "empty").mkdir()
    missing = runner.invoke(cli, ["preview", "--dataset", str(tmp_path / "empty"), "--output",
                                  str(tmp_path / "q.png")])
    assert missing.exit_code == 1 and "manifest.jsonl" in missing.output


def test_a_broken_exr_depth_is_refused_with_a_clear_reason(tmp_path):
    from dualpixel.io.images import read_depth

    path = tmp_path / "d.exr"
    path.write_bytes(b"v/1\x01 not really exr")
    with pytest.raises(InputFileError, match=r"d\.exr: .*(OpenEXR|cannot be decoded)"):
        read_depth(path)


def test_exr_depth_is_read_where_opencv_writes_it(tmp_path):
    """Issue #76: this passed on either branch; where OpenCV has no OpenEXR codec it now says
    it was skipped."""
    from dualpixel.io.images import read_depth

    depth = np.random.default_rng(0).uniform(1, 50, (20, 30)).astype(np.float32)
    path = tmp_path / "d.exr"
    try:
        written = cv2.imwrite(str(path), depth)
    except cv2.error:
        written = False
    if not written:
        pytest.skip("this OpenCV writes no OpenEXR (OPENCV_IO_ENABLE_OPENEXR unset)")
    np.testing.assert_allclose(read_depth(path), depth)


def test_grey_images_are_read_as_rgb(tmp_path):
    from dualpixel.io.images import read_rgb

    grey = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    image = read_rgb(tmp_path / "g.png")
    assert image.shape == (3, 4, 3)
    np.testing.assert_allclose(image[..., 0], grey / 255.0, atol=1e-7)
    assert np.array_equal(image[..., 0], image[..., 2])


def test_manifest_records_the_exact_render_mode_and_its_frames_differ(scene_dir, tmp_path):
    config = SynthConfig(noise=False, distortion=False, render_mode="exact", **FAST)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "exact", config, progress=False, limit=1)
    fast = SynthConfig(noise=False, distortion=False, **FAST)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "fast", fast, progress=False, limit=1)
    exact_rec, fast_rec = (json.loads((tmp_path / name / "manifest.jsonl").read_text())
                           for name in ("exact", "fast"))
    assert (exact_rec["render_mode"], fast_rec["render_mode"]) == ("exact", "fast")
    a = read16(tmp_path / "exact" / exact_rec["outputs"]["left"]).astype(float)
    b = read16(tmp_path / "fast" / fast_rec["outputs"]["left"]).astype(float)
    psnr = 10 * np.log10(65535.0**2 / max(np.mean((a - b) ** 2), 1e-12))
    assert 45 <= psnr < 200  # close to the reference, and really rendered by the other path


def test_unknown_render_mode_is_refused():
    with pytest.raises(ParameterError, match="render mode must be one of fast, exact"):
        SynthConfig(render_mode="quick")


def test_png_compression_changes_sizes_not_pixels(scene_dir, tmp_path):
    """Issue #36: the PNG level is not part of the content; a run may resume with another."""
    config = SynthConfig(seed=6, noise=False, **FAST)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "default", config, progress=False)
    synthesize_dataset(scene_dir, "rgbd", tmp_path / "mixed", config, progress=False, limit=3,
                       png_compression=0)
    stored = set((tmp_path / "mixed").rglob("*.png"))
    assert len(stored) == 3 * 4
    done = synthesize_dataset(scene_dir, "rgbd", tmp_path / "mixed", config, progress=False,
                              png_compression=9)
    assert done["status"] == "complete"
    files = sorted((tmp_path / "default").rglob("*.png"))
    assert len(files) == 8 * 4
    for path in files:
        other = tmp_path / "mixed" / path.relative_to(tmp_path / "default")
        assert np.array_equal(read16(path), read16(other))
        if other in stored and "target" in path.parts:  # the default compresses it
            assert other.stat().st_size > path.stat().st_size
        elif other in stored:  # the default stores the views (level 0) too: the same bytes
            assert other.read_bytes() == path.read_bytes()
    with pytest.raises(ParameterError, match="png_compression must be an integer in 0-9"):
        synthesize_dataset(scene_dir, "rgbd", tmp_path / "bad", config, progress=False,
                           png_compression=10)
    assert not (tmp_path / "bad").exists()


def test_quantise_rounds_to_the_nearest_level():
    from dualpixel.io.images import quantise

    rng = np.random.default_rng(0)
    values = rng.uniform(-0.2, 1.2, (64, 64, 3)).astype(np.float32)
    for bits, peak, dtype in ((8, 255, np.uint8), (16, 65535, np.uint16)):
        levels = quantise(values, bits)
        exact = np.rint(np.clip(values.astype(np.float64), 0, 1) * peak)
        assert levels.dtype == dtype
        assert np.abs(levels - exact).max() <= (0 if bits == 8 else 1)
        assert levels.min() == 0 and levels.max() == peak  # clipped, not wrapped
    # float32 scaling, halves to even (as np.rint), far-out values and infinities clipped
    edge = np.array([0.5, 1.5, 2.5, 65534.5, -3.0, 7e4, 1e30], np.float32) / np.float32(65535)
    edge = np.append(edge, np.float32([np.inf, -np.inf]))
    assert quantise(edge, 16).tolist() == [0, 2, 2, 65534, 0, 65535, 65535, 65535, 0]
    assert quantise(values[:, ::3, 1], 8).shape == (64, 22)  # strided views too


def test_linear_light_is_recorded_and_sums_the_views_light(scene_dir, tmp_path):
    """``light="linear"``: recorded in dataset.json and the manifest, the combined image is the
    views' summed light (not their mean value); the default records nothing new, so datasets
    made before the setting resume."""
    from dualpixel.optics.tone import srgb_to_linear

    assert "light" not in SynthConfig(**FAST).as_dict()
    out = tmp_path / "linear"
    synthesize_dataset(scene_dir, "rgbd", out, SynthConfig(noise=False, light="linear", **FAST),
                       progress=False)
    assert json.loads((out / "dataset.json").read_text())["config"]["light"] == "linear"
    record = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    assert record["light"] == "linear"
    views = [torch.from_numpy(read16(out / record["outputs"][k]) / 65535.0)
             for k in ("left", "right", "combined")]
    summed = (srgb_to_linear(views[0]) + srgb_to_linear(views[1])) / 2
    assert float((srgb_to_linear(views[2]) - summed).abs().max()) < 2e-4
    assert float((views[2] - (views[0] + views[1]) / 2).abs().max()) > 1e-3
    with pytest.raises(ParameterError, match="light must be one of"):
        SynthConfig(light="log")


def test_grey_datasets_store_the_green_channel(scene_dir, tmp_path):
    """``grey``: every image is the green channel alone, as a phone's DP data; not recorded
    when off, so datasets made before the setting resume."""
    assert "grey" not in SynthConfig(**FAST).as_dict()
    colour, grey = tmp_path / "colour", tmp_path / "grey"
    synthesize_dataset(scene_dir, "rgbd", colour, SynthConfig(noise=False, **FAST),
                       progress=False)
    synthesize_dataset(scene_dir, "rgbd", grey, SynthConfig(noise=False, grey=True, **FAST),
                       progress=False)
    assert json.loads((grey / "dataset.json").read_text())["config"]["grey"] is True
    record = json.loads((grey / "manifest.jsonl").read_text().splitlines()[0])
    for key in ("left", "right", "combined", "target"):
        stored = read16(grey / record["outputs"][key])
        assert stored.ndim == 2
        rgb = cv2.imread(str(colour / record["outputs"][key]), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(stored, rgb[..., 1])  # BGR: green in the middle


def test_raw_encoded_datasets_store_linear_values_above_the_black_level(scene_dir, tmp_path):
    """``encoding="linear"``: recorded in dataset.json and per frame; the stored combined image
    is the views' mean (light adds up in raw values); refused without linear light, and raw
    settings are refused for sRGB images. Not recorded when sRGB, so older datasets resume."""
    assert "encoding" not in SynthConfig(**FAST).as_dict()
    config = SynthConfig(noise=False, light="linear", encoding="linear", black_level=0.0625,
                         raw_gains=(0.5, 0.9), **FAST)
    assert SynthConfig.from_dict(config.as_dict()) == config
    out = tmp_path / "raw"
    synthesize_dataset(scene_dir, "rgbd", out, config, progress=False)
    saved = json.loads((out / "dataset.json").read_text())["config"]
    assert (saved["encoding"], saved["black_level"], saved["raw_gains"]) == ("linear", 0.0625,
                                                                             [0.5, 0.9])
    record = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    assert 0.5 <= record["raw"]["gain"] <= 0.9
    views = [read16(out / record["outputs"][k]) / 65535.0
             for k in ("left", "right", "combined", "target")]
    assert abs(views[2] - (views[0] + views[1]) / 2).max() < 2e-4
    ceiling = 0.0625 + (1 - 0.0625) * record["raw"]["gain"]
    for view in views:
        assert view.min() >= 0.0625 - 1e-4 and view.max() <= ceiling + 1e-4
    with pytest.raises(ParameterError, match="needs light 'linear'"):
        SynthConfig(encoding="linear", black_level=0.0625, **FAST)
    with pytest.raises(ParameterError, match="are for encoding 'linear'"):
        SynthConfig(black_level=0.0625, **FAST)
    with pytest.raises(ParameterError, match="encoding must be one of"):
        SynthConfig(encoding="log", **FAST)
    with pytest.raises(ParameterError, match="raw_gains must be"):
        SynthConfig(light="linear", encoding="linear", raw_gains=(0.0, 1.0), **FAST)
    for bad in ({"black_level": "dark"}, {"raw_gains": [0.5, "high"]}, {"raw_gains": "x"}):
        with pytest.raises(ParameterError, match=r"black_level|raw_gains"):  # no TypeError
            SynthConfig(light="linear", encoding="linear", **bad, **FAST)


def test_the_phone_profile_blurs_crops_like_the_phone_frame():
    from dualpixel.optics.thin_lens import DEFOCUS_PROFILES, coc_radius

    profile = DEFOCUS_PROFILES["phone-2016-crop"]
    rng = np.random.default_rng(0)
    far = [abs(float(coc_radius(np.array([1e6]), profile.lens(rng, 1.0, 840))[0]))
           for _ in range(200)]
    assert 1.0 <= min(far) and max(far) <= 12.0  # px, whatever the crop's width
    close = [abs(float(coc_radius(np.array([1e6]),
                                  DEFOCUS_PROFILES["phone-2016-close"].lens(rng, 1.0, 840))[0]))
             for _ in range(200)]
    assert 2.0 <= min(close) and max(close) <= 24.0 and np.median(close) > 1.8 * np.median(far)


def test_the_in_focus_blur_softens_the_stored_views_and_not_the_targets(scene_dir, tmp_path):
    """``base_blur``: recorded in dataset.json (not when 0, so older datasets resume) and per
    frame; the same seed's targets stay byte for byte, its views lose fine detail; bad ranges
    are refused naming the setting."""
    plain = SynthConfig(noise=False, **FAST)
    assert "base_blur" not in plain.as_dict()
    soft = SynthConfig(noise=False, base_blur=[0.8, 1.2], **FAST)
    assert soft.base_blur == (0.8, 1.2) and SynthConfig.from_dict(soft.as_dict()) == soft
    written = {}
    for name, config in (("plain", plain), ("soft", soft)):
        synthesize_dataset(scene_dir, "rgbd", tmp_path / name, config, progress=False)
        written[name] = json.loads((tmp_path / name / "manifest.jsonl").read_text()
                                   .splitlines()[0])
    assert "base_blur" not in written["plain"]
    assert 0.8 <= written["soft"]["base_blur"] <= 1.2
    assert json.loads((tmp_path / "soft" / "dataset.json").read_text())["config"][
        "base_blur"] == [0.8, 1.2]
    images = {name: {k: read16(tmp_path / name / record["outputs"][k]).astype(np.float64)
                     for k in ("left", "target")} for name, record in written.items()}
    np.testing.assert_array_equal(images["plain"]["target"], images["soft"]["target"])

    def detail(image):
        return np.abs(image - cv2.GaussianBlur(image, (0, 0), 1.5)).mean()

    assert detail(images["soft"]["left"]) < 0.8 * detail(images["plain"]["left"])
    for bad, message in (([0.5], "two stds"), ([1.0, 0.5], "LOW <= HIGH"),
                         ([-1.0, 0.5], "base_blur"), (["a", "b"], "base_blur")):
        with pytest.raises(ParameterError, match=message):
            SynthConfig(base_blur=bad, **FAST)
