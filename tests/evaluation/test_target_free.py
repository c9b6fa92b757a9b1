"""Target-free checks on synthetic DP frames whose answers are known: the identity changes
nothing, the sharp target gains sharpness and keeps brightness, and each fault a model can
make (darkening, halos, change where the views agree, invented texture) is seen where it is
made, and only there."""

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.evaluation.target_free import (
    MAX_BRIGHTNESS_CHANGE,
    check_deblurred,
    check_folder,
    compare_to_reference,
    flat_detail_error,
    local_brightness_error,
    markdown_table,
    model_methods,
    read_pairs,
)
from dualpixel.optics.tone import linear_to_srgb_array as encoded
from dualpixel.optics.tone import srgb_to_linear_array as linear


@pytest.fixture(scope="module")
def frame():
    """192x320, no noise or distortion, blurred in linear light as a lens blurs (so the target
    holds the same light as the views): a near plane in focus (the left 40 %), a textured
    background 3 m away behind the focus plane (about 2.5 px blur)."""
    import dualpixel

    rng = np.random.default_rng(4)
    noise = cv2.GaussianBlur(rng.standard_normal((192, 320, 3)).astype(np.float32), (0, 0), 2.0)
    rgb = np.clip(0.45 + 1.2 * noise, 0.02, 0.9)
    depth = np.where(np.arange(320)[None, :] < 128, 1.0, 3.0).repeat(192, 0).astype(np.float32)
    frame = dualpixel.synthesize(rgb, depth, lens_set="dslr-840", noise=False, distortion=False,
                                 light="linear")
    return {k: np.asarray(v, np.float32) for k, v in frame.items()}


def identity(frame):
    return encoded(0.5 * (linear(frame["left"]) + linear(frame["right"])))


def test_the_identity_changes_nothing(frame):
    report = check_deblurred(frame["left"], frame["right"], identity(frame))
    assert abs(report.brightness_change) < 1e-4 and report.local_brightness < 1e-4
    assert report.overshoot < 0.01 and report.halo_share == 0
    assert report.in_focus_change < 0.05
    assert report.flat_blocks == 0 and np.isnan(report.invented_texture)  # all textured
    assert report.sharpness_gain == pytest.approx(1.0, abs=0.01)


def test_blocks_are_told_apart_by_the_views(frame):
    """The near plane (left 40 %) is in focus, the background behind it is not."""
    report = check_deblurred(frame["left"], frame["right"], identity(frame))
    assert report.in_focus_blocks >= 6 and report.defocused_blocks >= 8
    assert report.in_focus_blocks + report.defocused_blocks <= report.blocks


def test_the_sharp_target_keeps_brightness_and_gains_sharpness(frame):
    report = check_deblurred(frame["left"], frame["right"], frame["target"])
    assert abs(report.brightness_change) < 0.005
    assert report.sharpness_gain > 1.3
    # the in-focus plane is the same in the target (blocks at its edge see some background)
    far_change = 255 * np.sqrt(np.mean((frame["target"] - identity(frame))[:, 160:] ** 2))
    assert far_change > 8 and report.in_focus_change < 0.2 * far_change


def test_the_local_brightness_error_against_a_known_target(frame):
    """Where the target is known (held-out synthetic frames): the perfect deblur scores 0, the
    unchanged blurred input more (its low-pass differs from the target's near edges), and a
    darkened target as much as it was darkened."""
    target, blurred = frame["target"], identity(frame)
    assert local_brightness_error(target, target) == 0.0
    assert local_brightness_error(blurred, target) > 1e-4
    darker = encoded(0.97 * linear(target))
    assert local_brightness_error(darker, target) == pytest.approx(0.03, abs=1e-3)
    assert local_brightness_error(darker, target) > 50 * local_brightness_error(blurred, target)
    with pytest.raises(ParameterError, match="must share one shape"):
        local_brightness_error(target[:, :64], target)
    with pytest.raises(ParameterError, match="encoding must be one of"):
        local_brightness_error(target, target, encoding="log")


def test_the_flat_detail_error_tells_restored_texture_from_invented():
    """A background of fine texture 3 m away: the blur leaves it flat in the views, so the
    checks count the target's texture there as invented (more than an output that invents
    noise). Against the known target, the perfect deblur scores 0 and invented noise more than
    the unchanged input; a frame with no flat block gives NaN."""
    rng = np.random.default_rng(5)
    coarse, fine = (cv2.GaussianBlur(rng.standard_normal((192, 320, 3)).astype(np.float32),
                                     (0, 0), sigma) for sigma in (2.0, 0.8))
    near = np.arange(320)[None, :] < 128
    rgb = np.clip(0.45 + np.where(near[..., None], 1.2 * coarse, 0.06 * fine), 0.02, 0.9)
    depth = np.where(near, 1.0, 3.0).repeat(192, 0).astype(np.float32)
    import dualpixel

    frame = {k: np.asarray(v, np.float32) for k, v in dualpixel.synthesize(
        rgb, depth, lens_set="dslr-840", noise=False, distortion=False, light="linear").items()}
    left, right, target = frame["left"], frame["right"], frame["target"]
    blurred = identity(frame)
    made_up = np.clip(blurred + 0.02 * cv2.GaussianBlur(
        rng.standard_normal(blurred.shape).astype(np.float32), (0, 0), 0.8), 0, 1)
    perfect = check_deblurred(left, right, target)
    assert perfect.flat_blocks >= 20 and perfect.invented_texture > 0.5
    assert check_deblurred(left, right, made_up).invented_texture < perfect.invented_texture
    assert flat_detail_error(left, right, target, target) == 0.0
    unchanged = flat_detail_error(left, right, blurred, target)
    assert unchanged > 0.5
    assert flat_detail_error(left, right, made_up, target) > unchanged + 0.03


def test_no_flat_block_gives_no_flat_detail_error(frame):
    assert np.isnan(flat_detail_error(frame["left"], frame["right"], identity(frame),
                                      frame["target"]))
    with pytest.raises(ParameterError, match="target"):
        flat_detail_error(frame["left"], frame["right"], identity(frame), frame["target"][:, :64])


@pytest.mark.parametrize("gain", [0.95, 1.03])
def test_a_gain_in_linear_light_is_measured(frame, gain):
    output = encoded(np.clip(linear(identity(frame)) * gain, 0, 1))
    report = check_deblurred(frame["left"], frame["right"], output)
    assert report.brightness_change == pytest.approx(gain - 1, abs=0.002)
    assert report.local_brightness == pytest.approx(abs(gain - 1), rel=0.1)


def test_linear_views_are_measured_in_their_own_encoding(frame):
    left, right = linear(frame["left"]), linear(frame["right"])
    output = 0.5 * (left + right) * 0.9
    report = check_deblurred(left, right, output, encoding="linear")
    assert report.brightness_change == pytest.approx(-0.1, abs=0.002)
    # grey views, one channel
    grey = check_deblurred(left[..., 1:2], right[..., 1:2], output[..., 1:2], encoding="linear")
    assert grey.brightness_change == pytest.approx(-0.1, abs=0.002)


def test_halos_from_over_sharpening_are_seen(frame):
    image = identity(frame)
    sharpened = np.clip(image + 3.0 * (image - cv2.GaussianBlur(image, (0, 0), 3.0)), 0, 1)
    halo = check_deblurred(frame["left"], frame["right"], sharpened)
    sharp = check_deblurred(frame["left"], frame["right"], frame["target"])
    assert halo.overshoot > 3 * sharp.overshoot and halo.overshoot > 1.0
    assert halo.halo_share > 3 * sharp.halo_share


def test_change_counts_only_where_the_views_agree(frame):
    image = identity(frame)
    rng = np.random.default_rng(0)
    blotches = cv2.GaussianBlur(rng.standard_normal(image.shape[:2]).astype(np.float32),
                                (0, 0), 3.0)[..., None] * 0.2
    near, far = image.copy(), image.copy()
    near[:, :110] = np.clip(near[:, :110] + blotches[:, :110], 0, 1)
    far[:, 150:] = np.clip(far[:, 150:] + blotches[:, 150:], 0, 1)
    changed_near = check_deblurred(frame["left"], frame["right"], near).in_focus_change
    changed_far = check_deblurred(frame["left"], frame["right"], far).in_focus_change
    assert changed_near > 2.0 and changed_far < 0.2


def test_texture_invented_on_a_flat_region_is_seen():
    height, width = 128, 256
    rng = np.random.default_rng(1)
    view = np.full((height, width, 3), 0.4, np.float32)
    texture = cv2.GaussianBlur(rng.standard_normal((height, width)).astype(np.float32), (0, 0),
                               1.5)
    view[:, width // 2:] += 0.3 * texture[:, width // 2:, None]  # right half textured
    view = np.clip(view, 0, 1)
    blotchy = view.copy()
    blotchy[:, : width // 2] += 0.03 * cv2.GaussianBlur(
        rng.standard_normal((height, width // 2)).astype(np.float32), (0, 0), 1.0)[..., None]
    clean = check_deblurred(view, view, view)
    made_up = check_deblurred(view, view, np.clip(blotchy, 0, 1))
    assert clean.flat_blocks >= 10 and clean.invented_texture < 0.01
    assert made_up.invented_texture > 0.5


def test_bad_inputs_are_refused(frame):
    with pytest.raises(ParameterError, match="encoding"):
        check_deblurred(frame["left"], frame["right"], frame["target"], encoding="log")
    with pytest.raises(ParameterError, match="share one shape"):
        check_deblurred(frame["left"], frame["right"], frame["target"][:, :-1])
    with pytest.raises(ParameterError, match="at least"):
        check_deblurred(frame["left"][:40], frame["right"][:40], frame["target"][:40])
    bad = frame["target"].copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ParameterError, match="NaN"):
        check_deblurred(frame["left"], frame["right"], bad)


def write_pairs(root, frame, names=("a", "b")):
    for name in names:
        (root / name).mkdir(parents=True)
        for view in ("left", "right"):
            cv2.imwrite(str(root / name / f"{view}.png"),
                        np.rint(frame[view][..., ::-1] * 255).astype(np.uint8))
    return root


def test_folders_reference_and_table(frame, tmp_path):
    root = write_pairs(tmp_path / "pairs", frame)
    assert [name for name, _, _ in read_pairs(root)] == ["a", "b"]

    def darker(left, right):
        return encoded(np.clip(0.5 * (linear(left) + linear(right)) * 0.97, 0, 1))

    def mean(left, right):
        return encoded(0.5 * (linear(left) + linear(right)))

    rows = check_folder(root, {"mean": mean, "darker": darker})
    assert [(r["pair"], r["method"]) for r in rows] == [
        ("a", "mean"), ("a", "darker"), ("b", "mean"), ("b", "darker")]
    assert check_folder(root, {"mean": mean, "darker": darker}, encoding="srgb") == rows
    with pytest.raises(ParameterError, match="encoding must be one of"):
        check_folder(root, {"mean": mean}, encoding="raw")
    findings = compare_to_reference(rows, "mean")
    assert any("darker changes the brightness by -3" in f for f in findings)
    assert any("darker local_brightness" in f for f in findings)
    assert not any(": mean " in f for f in findings)
    assert MAX_BRIGHTNESS_CHANGE == 0.01
    table = markdown_table(rows)
    assert "| a | darker | -3.0" in table and "**mean of 2** | darker" in table
    with pytest.raises(ParameterError, match="reference"):
        compare_to_reference(rows, "other")


def test_check_model_command(frame, tmp_path, tiny_checkpoint):
    root = write_pairs(tmp_path / "pairs", frame, names=("one",))
    out = tmp_path / "report"
    result = CliRunner().invoke(cli, ["check-model", "--input", str(root), "--checkpoint",
                                      str(tiny_checkpoint), "--reference", str(tiny_checkpoint),
                                      "-o", str(out), "--device", "cpu", "--brightness", "model",
                                      "--brightness", "tied", "--overshoot", "model",
                                      "--overshoot", "limited", "--flips", "off", "--flips", "off"])
    assert result.exit_code == 0, result.output
    csv = (out / "target_free.csv").read_text().splitlines()
    assert csv[0].startswith("pair,method,brightness_change") and len(csv) == 5
    rows = {line.split(",")[1].removeprefix(str(tiny_checkpoint)): line.split(",")
            for line in csv[1:]}
    assert sorted(rows) == ["", "+limited", "+limited+tied", "+tied"]
    assert abs(float(rows["+tied"][2])) < 0.002  # its brightness change over the frame
    # the limit never adds overshoot (column 6); one network pass serves all four modes
    assert float(rows["+limited"][5]) <= float(rows[""][5])
    assert "Against" in (out / "target_free.md").read_text()
    wrong = CliRunner().invoke(cli, ["check-model", "--input", str(root), "--reference", "x",
                                     "-o", str(out)])
    assert wrong.exit_code == 2 and "--reference" in wrong.output
    assert "Traceback" not in wrong.output
    empty = tmp_path / "empty"
    empty.mkdir()
    nothing = CliRunner().invoke(cli, ["check-model", "--input", str(empty), "-o", str(out)])
    assert nothing.exit_code != 0 and "no scene folders" in nothing.output


def test_check_model_takes_linear_raw_views_in_the_files_units(frame, tmp_path,
                                                               tiny_checkpoint):
    """14-bit raw grey views above a black level of 1024, as a phone stores them: read as light
    (black level off), checked in linear light, the model fed as deblur feeds it."""
    from dualpixel.inference.encoding import ViewEncoding

    root = tmp_path / "raw"
    (root / "one").mkdir(parents=True)
    for view in ("left", "right"):
        light = linear(frame[view][..., 1])
        raw = np.rint(1024 + light * 0.6 * (16383 - 1024)).astype(np.uint16)
        cv2.imwrite(str(root / "one" / f"{view}.png"), raw)
    encoding = ViewEncoding("linear", 1024, 16383)
    (_, left, _), = read_pairs(root, encoding=encoding)
    np.testing.assert_allclose(left[..., 0], 0.6 * linear(frame["left"][..., 1]), atol=1e-4)
    out = tmp_path / "report"
    result = CliRunner().invoke(cli, ["check-model", "--input", str(root), "--checkpoint",
                                      str(tiny_checkpoint), "-o", str(out), "--device", "cpu",
                                      "--brightness", "tied", "--encoding", "linear",
                                      "--black-level", "1024", "--white-level", "16383"])
    assert result.exit_code == 0, result.output
    row = (out / "target_free.csv").read_text().splitlines()[1].split(",")
    assert abs(float(row[2])) < 0.005  # brightness change over the frame: the light kept


def test_the_modes_of_a_checkpoint_share_its_network_pass(frame, tiny_checkpoint, tmp_path):
    import torch

    from dualpixel.inference import Deblurrer
    from dualpixel.models import load_model, save_model

    left, right = frame["left"], frame["right"]
    model = load_model(tiny_checkpoint)  # untrained (the identity): perturbed so flips matter
    torch.manual_seed(1)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.05 * torch.randn_like(p))
    checkpoint = tmp_path / "perturbed.safetensors"
    save_model(checkpoint, model)
    methods = model_methods([str(checkpoint)], device="cpu", precision="fp32",
                            brightness=("model", "tied"), overshoot=("model", "limited"),
                            flips=(False, True))
    assert len(methods) == 8
    for name, method in methods.items():
        limit = "limited" if "+limited" in name else "model"
        tie = "tied" if "+tied" in name else "model"
        alone = Deblurrer(model, precision="fp32", brightness=tie, overshoot=limit,
                          flips="+flips" in name)
        np.testing.assert_allclose(method(left, right), alone(left, right), atol=1e-6)
    flipped = methods[str(checkpoint) + "+flips"](left, right)
    assert np.abs(flipped - methods[str(checkpoint)](left, right)).max() > 1e-3


def test_eval_runs_the_view_checks(shared_dir, tmp_path):
    """Swapped views score lower; eval now says why, as deblur does."""
    import json
    import shutil

    scene = tmp_path / "swapped" / "scene_02"
    scene.mkdir(parents=True)
    source = shared_dir / "data" / "canon-dp-real" / "scene_02"
    shutil.copy(source / "view0.png", scene / "view1.png")
    shutil.copy(source / "view1.png", scene / "view0.png")
    shutil.copy(source / "target.png", scene / "target.png")
    out = tmp_path / "eval"
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(tmp_path / "swapped"),
                                      "--no-model", "--no-niqe", "--figures", "0", "-o",
                                      str(out)])
    assert result.exit_code == 0, result.output
    findings = json.loads((out / "summary.json").read_text())["view_findings"]
    assert [f["code"] for f in findings] == ["swapped"]


def test_a_reference_is_a_method_or_a_checkpoint_checked_one_way():
    from dualpixel.evaluation.target_free import method_settings, reference_method

    named = method_settings(["rdpd-light", "rdpd-wide"], flips=[False])
    assert reference_method(named, "rdpd-light") == "rdpd-light+tied"  # as it ships
    assert reference_method(named, "rdpd-wide") == "rdpd-wide"
    assert reference_method(named, "rdpd-light+tied") == "rdpd-light+tied"
    several = method_settings(["rdpd-light"], overshoot=["limited", "model"])
    with pytest.raises(ParameterError, match=r"several settings.*rdpd-light\+limited\+tied"):
        reference_method(several, "rdpd-light")
    with pytest.raises(ParameterError, match="not one of the checked models"):
        reference_method(named, "rdpd-plus")


def test_the_output_modes_on_a_known_over_sharpening_darkening_model(frame, tiny_checkpoint):
    """Issue #76: the untrained checkpoint is the identity, where limited and plain overshoot
    are equal; here the network's output is a known one (an unsharp mask of the combined image,
    its light then scaled by 0.9: over-sharpened and, by its overshoot, 24 % brighter) through
    the deblurrer's own output modes: the limit must take most of the overshoot and halos away,
    the tie the brightness change, and neither may touch an output that is already within range
    and at the input's brightness (the identity)."""
    from dualpixel.inference import Deblurrer
    from dualpixel.models import load_model

    left, right = frame["left"], frame["right"]
    image = identity(frame)
    known = np.clip(image + 3.0 * (image - cv2.GaussianBlur(image, (0, 0), 3.0)), 0, 1)
    known = encoded(0.9 * linear(known)).astype(np.float32)
    deblurrer = Deblurrer(load_model(tiny_checkpoint), precision="fp32")
    report = {(tie, limit): check_deblurred(left, right, deblurrer.finish(
        known, left, right, brightness=tie, overshoot=limit))
        for tie in ("model", "tied") for limit in ("model", "limited")}
    plain, limited = report["model", "model"], report["model", "limited"]
    assert plain.overshoot > 10.0 and limited.overshoot < 0.3 * plain.overshoot  # 21.1, 3.0
    assert limited.halo_share < 0.6 * plain.halo_share  # 0.70 -> 0.32
    assert plain.brightness_change > 0.1  # +0.24
    assert abs(report["tied", "model"].brightness_change) < 0.005
    assert abs(report["tied", "limited"].brightness_change) < 0.005
    assert report["tied", "model"].local_brightness < 0.1 * plain.local_brightness
    for tie in ("model", "tied"):
        for limit in ("model", "limited"):
            kept = deblurrer.finish(image, left, right, brightness=tie, overshoot=limit)
            assert np.abs(kept - image).max() < 3 / 255, (tie, limit)


def test_eval_trusts_the_orientation_of_a_set_synth_made(tmp_path):
    """A frame focused far has its blur in front of the focus plane, which the swapped-views
    guess reads as exchanged views: right for a stranger's pair, wrong for a set ``synth``
    wrote, whose left is the synthesizer's left."""
    import json
    import shutil

    import cv2

    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset

    rng = np.random.default_rng(5)
    noise = cv2.GaussianBlur(rng.standard_normal((192, 320, 3)).astype(np.float32), (0, 0), 2.0)
    scene = tmp_path / "scenes" / "seq_000"
    (scene / "rgb").mkdir(parents=True)
    (scene / "depth").mkdir()
    rgb = np.clip(0.45 + 1.2 * noise, 0.02, 0.9)
    cv2.imwrite(str(scene / "rgb" / "frame_0000.png"),
                np.rint(rgb[..., ::-1] * 255).astype(np.uint8))
    # the left quarter 1.5 m away, the rest 3 m, where the scene is focused
    depth = np.where(np.arange(320)[None, :] < 80, 1.5, 3.0).repeat(192, 0)
    np.save(scene / "depth" / "frame_0000.npy", depth.astype(np.float32))
    (scene / "scene.json").write_text(json.dumps({"focus_distance": 3.0}))
    made = tmp_path / "made"
    synthesize_dataset(tmp_path / "scenes", "rgbd", made,
                       SynthConfig(lens_sets=("dslr-840",), noise=False, distortion=False,
                                   split="test"), progress=False)
    stranger = tmp_path / "stranger"  # the same files without the synthesizer's description
    shutil.copytree(made, stranger, ignore=shutil.ignore_patterns("dataset.json"))
    codes = {}
    for name, root in (("made", made), ("stranger", stranger)):
        out = tmp_path / f"eval-{name}"
        result = CliRunner().invoke(cli, ["eval", "--dataset", str(root), "--split", "test",
                                          "--no-model", "--no-niqe", "--figures", "0", "-o",
                                          str(out)])
        assert result.exit_code == 0, result.output
        findings = json.loads((out / "summary.json").read_text())["view_findings"]
        codes[name] = [f["code"] for f in findings]
    assert codes == {"made": [], "stranger": ["swapped"]}
