"""Phone and raw DP views end to end: green-only (grey) views and linear raw views go in through
the documented mode and come back in their own encoding and channel count; mistakes get a
clear error or a warning that names them."""

import warnings

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

import dualpixel
from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.inference.encoding import (
    ViewEncoding,
    encoding_findings,
    flat_field_gain,
    from_model,
    to_model,
)
from dualpixel.optics.tone import srgb_to_linear

BLACK, WHITE = 1024, 16383  # 14-bit raw data above a black level, stored in 16-bit PNGs


@pytest.fixture(scope="module")
def raw_pair(behind_focus_frame):
    """The fixture frame's green channel as raw 16-bit views: linear light, black level 1024,
    white level 16383, each view a quarter of full scale at most (raw data are dark)."""
    views = []
    for key in ("left", "right"):
        green = srgb_to_linear(torch.from_numpy(np.asarray(behind_focus_frame[key][..., 1],
                                                           np.float32))).numpy()
        views.append(np.rint(BLACK + 0.25 * green * (WHITE - BLACK)).astype(np.uint16))
    return views


def test_model_round_trip_keeps_encoding_and_channels(raw_pair):
    left = raw_pair[0][None, ..., None].astype(np.float32) / 65535
    encoding = ViewEncoding("linear", BLACK, WHITE)
    model_left, _ = to_model(left, left, encoding, scale=65535)
    assert model_left.shape == (*left.shape[:3], 3)
    assert 0 <= model_left.min() and model_left.max() <= 1
    back = from_model(model_left, encoding, 1, scale=65535)
    assert back.shape == left.shape
    np.testing.assert_allclose(back, left, atol=1e-5)


def test_api_grey_linear_views_come_back_grey_and_linear(raw_pair, tiny_checkpoint):
    left, right = raw_pair
    out = dualpixel.deblur(left, right, model=tiny_checkpoint, device="cpu",
                           encoding="linear", black_level=BLACK, white_level=WHITE)
    assert out.shape == left.shape and out.dtype == np.float32  # (H, W) in, (H, W) out
    # the same raw values: at least the black level, about as bright as the views' mean
    assert out.min() >= BLACK / 65535 - 1e-6
    mean_in = (left.astype(np.float64) + right) / 2 / 65535
    assert out.mean() == pytest.approx(mean_in.mean(), rel=0.1)
    # torch (1, H, W) in: (1, H, W) out; and (H, W, 1) numpy: (H, W, 1)
    as_torch = dualpixel.deblur(torch.from_numpy(left.astype(np.float32) / 65535)[None],
                                torch.from_numpy(right.astype(np.float32) / 65535)[None],
                                model=tiny_checkpoint, device="cpu", encoding="linear",
                                black_level=BLACK / 65535, white_level=WHITE / 65535)
    assert tuple(as_torch.shape) == (1, *left.shape)
    np.testing.assert_allclose(as_torch[0].numpy(), out, atol=2e-5)
    assert dualpixel.deblur(left[..., None], right[..., None], model=tiny_checkpoint,
                            device="cpu", encoding="linear", black_level=BLACK,
                            white_level=WHITE).shape == (*left.shape, 1)


def test_api_refuses_mixed_or_incomplete_views(raw_pair, tiny_checkpoint):
    left, right = raw_pair
    with pytest.raises(ParameterError, match="black_level"):
        dualpixel.deblur(left, right, model=tiny_checkpoint, encoding="linear", white_level=WHITE)
    with pytest.raises(ParameterError, match="black_level < white_level"):
        dualpixel.deblur(left, right, model=tiny_checkpoint, encoding="linear",
                         black_level=WHITE, white_level=BLACK)
    with pytest.raises(ParameterError, match="linear views"):
        dualpixel.deblur(left, right, model=tiny_checkpoint, black_level=BLACK)
    with pytest.raises(ParameterError, match="channel"):
        dualpixel.deblur(left, np.repeat(right[..., None], 3, axis=2), model=tiny_checkpoint)
    with pytest.raises(ParameterError, match="encoding"):
        ViewEncoding("log")


def test_looks_linear_and_looks_encoded_warnings(raw_pair, behind_focus_frame, tiny_checkpoint):
    left, right = (v[..., None].astype(np.float32) / 65535 for v in raw_pair)
    assert [f.code for f in encoding_findings(left, right, "srgb")] == ["looks-linear"]
    assert encoding_findings(left, right, "linear") == []
    bright = np.asarray(behind_focus_frame["left"], np.float32)
    assert [f.code for f in encoding_findings(bright, bright, "linear")] == ["looks-encoded"]
    assert encoding_findings(bright, bright, "srgb") == []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dualpixel.deblur(raw_pair[0], raw_pair[1], model=tiny_checkpoint, device="cpu")
    assert any("--encoding linear" in str(w.message) for w in caught)


def test_flat_field_gain_evens_out_shading():
    height, width = 64, 96
    ramp = np.linspace(0.9, 1.1, width, dtype=np.float32)[None, :].repeat(height, 0)
    left = np.full((height, width, 1), 0.2, np.float32)
    right = 0.2 * ramp[..., None]
    gain = flat_field_gain(left, right, sigma=2.0)
    np.testing.assert_allclose(gain[:, 10:-10] * ramp[:, 10:-10], 1.0, atol=0.01)
    with pytest.raises(ParameterError, match="black level"):
        flat_field_gain(left, right, black_level=0.5)


def write_grey16(path, image):
    assert cv2.imwrite(str(path), image)
    return path


def test_cli_grey_raw_views_written_back_as_grey_raw(raw_pair, tiny_checkpoint, tmp_path):
    left = write_grey16(tmp_path / "left.png", raw_pair[0])
    right = write_grey16(tmp_path / "right.png", raw_pair[1])
    out = tmp_path / "out.png"
    result = CliRunner().invoke(cli, [
        "deblur", "--left", str(left), "--right", str(right), "-o", str(out), "--checkpoint",
        str(tiny_checkpoint), "--device", "cpu", "--encoding", "linear", "--black-level",
        str(BLACK), "--white-level", str(WHITE)])
    assert result.exit_code == 0, result.output
    written = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    assert written.dtype == np.uint16 and written.shape == raw_pair[0].shape
    assert written.min() >= BLACK - 1
    # flat-field gain from a capture of an even surface
    flat = write_grey16(tmp_path / "flat.png", np.full_like(raw_pair[0], 5000))
    result = CliRunner().invoke(cli, [
        "deblur", "--left", str(left), "--right", str(right), "-o", str(tmp_path / "o2.png"),
        "--checkpoint", str(tiny_checkpoint), "--device", "cpu", "--encoding", "linear",
        "--black-level", str(BLACK), "--white-level", str(WHITE), "--flat-field", str(flat),
        str(flat)])
    assert result.exit_code == 0, result.output
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "o2.png"), cv2.IMREAD_UNCHANGED),
                                  written)
    # declared as display values, the dark raw views give a warning that names the mode
    result = CliRunner().invoke(cli, [
        "deblur", "--left", str(left), "--right", str(right), "-o", str(tmp_path / "o3.png"),
        "--checkpoint", str(tiny_checkpoint), "--device", "cpu"])
    assert result.exit_code == 0 and "--encoding linear" in result.output


def test_cli_bad_phone_inputs_are_clear_errors(raw_pair, tiny_checkpoint, tmp_path):
    left = write_grey16(tmp_path / "left.png", raw_pair[0])
    colour = tmp_path / "right.png"
    cv2.imwrite(str(colour), np.repeat(raw_pair[1][..., None], 3, axis=2))
    base = ["deblur", "--left", str(left), "--checkpoint", str(tiny_checkpoint), "--device",
            "cpu", "-o", str(tmp_path / "out.png")]
    mixed = CliRunner().invoke(cli, [*base, "--right", str(colour)])
    assert mixed.exit_code != 0 and "right.png" in mixed.output and "grey" in mixed.output
    no_black = CliRunner().invoke(cli, [*base, "--right", str(left), "--encoding", "linear",
                                        "--white-level", "16383"])
    assert no_black.exit_code != 0 and "--black-level" in no_black.output
    # Issue #72: a flat field of another size names the views' file and the option; a flat field
    # that is black names the flat field's file
    linear = ["--right", str(tmp_path / "right_grey.png"), "--encoding", "linear",
              "--black-level", str(BLACK), "--white-level", str(WHITE)]
    write_grey16(tmp_path / "right_grey.png", raw_pair[1])
    small = write_grey16(tmp_path / "flat_small.png", np.full((16, 24), 5000, np.uint16))
    other_size = CliRunner().invoke(cli, [*base, *linear, "--flat-field", str(small), str(small)])
    assert other_size.exit_code == 1, other_size.output
    assert "left.png: the right view's gain map (a flat field, --flat-field) is 24x16" in \
        other_size.output
    dark = write_grey16(tmp_path / "flat_dark.png", np.full_like(raw_pair[0], BLACK))
    black = CliRunner().invoke(cli, [*base, *linear, "--flat-field", str(dark), str(dark)])
    assert black.exit_code == 1 and "flat_dark.png: as a flat field: " in black.output
    for result in (mixed, no_black, other_size, black):
        assert "Traceback" not in result.output


def test_pixel_dp_import_turns_the_views_and_writes_the_dpdd_layout(raw_pair, tiny_checkpoint,
                                                                     tmp_path):
    """Captures stored as the public Pixel DP releases store them: one folder per capture,
    16-bit grey left/right PNGs, the DP baseline vertical."""
    stored = [np.rot90(v, -1) for v in raw_pair]  # as the phone stores them: turned clockwise
    captures = []
    for index, names in enumerate((("result_leftPd_center.png", "result_rightPd_center.png"),
                                   ("left.png", "right.png"))):
        folder = tmp_path / "release" / f"capture{index}"
        folder.mkdir(parents=True)
        for name, view in zip(names, stored):
            write_grey16(folder / name, np.ascontiguousarray(view))
        captures.append(folder)
    out = tmp_path / "dpdd"
    result = CliRunner().invoke(cli, ["import-pixel-dp", *map(str, captures), "-o", str(out)])
    assert result.exit_code == 0, result.output
    left = cv2.imread(str(out / "test_l/source/capture0.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(left, raw_pair[0])  # turned back: baseline horizontal
    combined = cv2.imread(str(out / "test_c/source/capture1.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_allclose(combined, (raw_pair[0].astype(float) + raw_pair[1]) / 2, atol=1)
    deblurred = CliRunner().invoke(cli, [
        "deblur", "--input", str(out), "-o", str(tmp_path / "sharp"), "--checkpoint",
        str(tiny_checkpoint), "--device", "cpu", "--encoding", "linear", "--black-level",
        str(BLACK), "--white-level", str(WHITE)])
    assert deblurred.exit_code == 0, deblurred.output
    sharp = cv2.imread(str(tmp_path / "sharp" / "capture0.png"), cv2.IMREAD_UNCHANGED)
    assert sharp.dtype == np.uint16 and sharp.shape == raw_pair[0].shape
    # a folder without a right view, a colour view: errors naming the folder or file
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    write_grey16(lonely / "left.png", raw_pair[0])
    bad = CliRunner().invoke(cli, ["import-pixel-dp", str(lonely), "-o", str(tmp_path / "x")])
    assert bad.exit_code != 0 and "lonely" in bad.output and "right" in bad.output
    colour = tmp_path / "colour"
    colour.mkdir()
    cv2.imwrite(str(colour / "left.png"), np.zeros((8, 8, 3), np.uint16))
    write_grey16(colour / "right.png", np.zeros((8, 8), np.uint16))
    bad = CliRunner().invoke(cli, ["import-pixel-dp", str(colour), "-o", str(tmp_path / "y")])
    assert bad.exit_code != 0 and "colour image" in bad.output
    assert not (tmp_path / "y" / "test_l" / "source" / "colour.png").exists()


def test_exposure_gain_known_answers():
    from dualpixel.inference.encoding import EXPOSURE_MAX_GAIN, EXPOSURE_TARGET, exposure_gain

    dark = np.full((100, 100, 1), 0.05, np.float32)
    assert exposure_gain(dark, dark) == pytest.approx(EXPOSURE_TARGET / 0.05)
    assert exposure_gain(dark * 0, dark * 0) == EXPOSURE_MAX_GAIN  # black stays black
    bright = np.full((100, 100, 3), 0.9, np.float32)
    assert exposure_gain(bright, bright) == 1.0  # never darkened
    # a small bright patch (0.5 % of the frame, above the 99th percentile) is never clipped
    patchy = dark.copy()
    patchy[:5, :10] = 0.4
    assert exposure_gain(patchy, patchy) == pytest.approx(1 / 0.4)
    # a batch: one gain per pair, shaped to scale (N, H, W, C)
    batch = np.stack([dark, np.full_like(dark, 0.35)])
    gains = exposure_gain(batch, batch)
    assert gains.shape == (2, 1, 1, 1)
    np.testing.assert_allclose(gains.ravel(), [EXPOSURE_TARGET / 0.05, 2.0], rtol=1e-5)


def test_auto_exposure_hands_the_network_one_view_whatever_the_exposure(raw_pair):
    """Synthetic raw views of one scene at several exposures reach the network as the same
    views (up to the views' rounding), and the output comes back at each one's exposure; off,
    the network sees each exposure as it is."""
    light = [(v.astype(np.float64) - BLACK) / (WHITE - BLACK) for v in raw_pair]  # <= 0.25
    seen, outputs = [], []
    for exposure in (0.5, 1.0, 2.0, 3.0):  # peaks at 12 % to 75 % of full scale
        views = [(BLACK + exposure * v * (WHITE - BLACK)) / 65535 for v in light]
        views = [v[..., None].astype(np.float32) for v in views]
        encoding = ViewEncoding("linear", BLACK, WHITE).exposed(*views, scale=65535)
        assert encoding.light_gain > 1.0
        model_left, _ = to_model(*views, encoding, scale=65535)
        seen.append(model_left)
        out = from_model(model_left, encoding, 1, scale=65535)  # an identity network
        np.testing.assert_allclose(out, views[0], atol=1e-5)
        off = ViewEncoding("linear", BLACK, WHITE, auto_exposure=False)
        outputs.append(to_model(*views, off, scale=65535)[0])
    for other in seen[1:]:
        np.testing.assert_allclose(other, seen[0], atol=2e-3)
    assert abs(float(outputs[0].mean()) - float(outputs[-1].mean())) > 0.1


def test_auto_exposure_in_the_api_and_cli(raw_pair, tmp_path):
    """The shipped model on dark raw views: with auto exposure (the default) its output at two
    exposures agrees once scaled back; off, the option changes the output."""
    light = [(v.astype(np.float64) - BLACK) / (WHITE - BLACK) for v in raw_pair]
    outs = {}
    for exposure in (0.5, 1.5):
        views = [((BLACK + exposure * v * (WHITE - BLACK)) / 65535).astype(np.float32)
                 for v in light]
        for auto in (True, False):
            out = dualpixel.deblur(*views, device="cpu", encoding="linear",
                                   black_level=BLACK / 65535, white_level=WHITE / 65535,
                                   auto_exposure=auto)
            outs[exposure, auto] = (out * 65535 - BLACK) / (WHITE - BLACK) / exposure
    same = np.abs(outs[0.5, True] - outs[1.5, True]).mean()
    differ = np.abs(outs[0.5, False] - outs[1.5, False]).mean()
    assert same < 1e-5 and differ > 3e-4, (same, differ)
    left = write_grey16(tmp_path / "left.png", raw_pair[0])
    right = write_grey16(tmp_path / "right.png", raw_pair[1])
    written = {}
    for flag in ("--auto-exposure", "--no-auto-exposure"):
        out = tmp_path / f"{flag}.png"
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(left), "--right", str(right), "-o", str(out), "--device",
            "cpu", "--encoding", "linear", "--black-level", str(BLACK), "--white-level",
            str(WHITE), flag])
        assert result.exit_code == 0, result.output
        written[flag] = cv2.imread(str(out), cv2.IMREAD_UNCHANGED).astype(np.float64)
    assert np.abs(written["--auto-exposure"] - written["--no-auto-exposure"]).mean() > 2


def test_one_file_is_not_a_pair(raw_pair, tiny_checkpoint, tmp_path):
    left = write_grey16(tmp_path / "left.png", raw_pair[0])
    link = tmp_path / "also-left.png"
    link.symlink_to(left)
    for right in (left, link):
        result = CliRunner().invoke(cli, ["deblur", "--left", str(left), "--right", str(right),
                                          "--checkpoint", str(tiny_checkpoint), "--device",
                                          "cpu", "-o", str(tmp_path / "out.png")])
        assert result.exit_code == 1 and "is --left too" in result.output, result.output
        assert "Traceback" not in result.output and not (tmp_path / "out.png").exists()


def test_levels_that_do_not_fit_the_views_are_named(raw_pair, tiny_checkpoint, tmp_path):
    """Levels of another bit depth, a black level above every value: refused naming the file
    and what the views hold (they ran to a constant or saturated image)."""
    eight_bit = tmp_path / "left8.png"
    cv2.imwrite(str(eight_bit), (raw_pair[0] // 257).astype(np.uint8))
    right8 = tmp_path / "right8.png"
    cv2.imwrite(str(right8), (raw_pair[1] // 257).astype(np.uint8))
    left = write_grey16(tmp_path / "left.png", raw_pair[0])
    right = write_grey16(tmp_path / "right.png", raw_pair[1])
    for views, levels, words in (
            ((eight_bit, right8), ("1024", "16383"), ("left8.png", "beyond", "full scale (255)")),
            ((left, right), ("60000", "65535"), ("left.png", "black_level 60000", "largest"))):
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(views[0]), "--right", str(views[1]), "--checkpoint",
            str(tiny_checkpoint), "--device", "cpu", "-o", str(tmp_path / "out.png"),
            "--encoding", "linear", "--black-level", levels[0], "--white-level", levels[1]])
        assert result.exit_code == 1 and "Traceback" not in result.output, result.output
        for word in words:
            assert word in result.output, result.output
        assert not (tmp_path / "out.png").exists()
    with pytest.raises(ParameterError, match="beyond these views' full scale"):
        dualpixel.deblur(raw_pair[0], raw_pair[1], model=tiny_checkpoint, device="cpu",
                         encoding="linear", black_level=0, white_level=70000)


@pytest.mark.parametrize("name", ["pixel-gif-02", "pixel-gif-05"])
def test_pixel_dp_import_gives_real_captures_the_documented_orientation(name, shared_dir,
                                                                        tmp_path):
    """Issue #76, from data rather than the test's own assumption: two real Pixel 4 pairs of
    ../shared/data/dp-real-nogt, whose README documents how they were taken from the authors'
    release (frame 0 left, frame 1 right, turned 90 degrees counter-clockwise) and measures the
    right view's content to the right of the left's behind the focus (medians +0.92 and +2.77 px,
    most tiles positive), put back as the release stores them and imported: both views come back
    as documented, with that disparity; turned the other way, the sign flips."""
    from dualpixel.data.statistics import block_disparity

    pair = shared_dir / "data" / "dp-real-nogt" / name
    views = [cv2.imread(str(pair / f"{side}.png"), cv2.IMREAD_UNCHANGED)
             for side in ("left", "right")]
    capture = tmp_path / "release" / name
    capture.mkdir(parents=True)
    for side, view in zip(("left", "right"), views):  # stored baseline vertical: turned back
        cv2.imwrite(str(capture / f"result_{side}Pd_center.png"), np.rot90(view, -1).copy())
    medians = {}
    for rotate in ("ccw", "cw"):
        out = tmp_path / rotate
        result = CliRunner().invoke(cli, ["import-pixel-dp", str(capture), "-o", str(out),
                                          "--rotate", rotate])
        assert result.exit_code == 0, result.output
        left, right = (cv2.imread(str(out / f"test_{s}/source/{name}.png"),
                                  cv2.IMREAD_UNCHANGED) for s in ("l", "r"))
        if rotate == "ccw":
            np.testing.assert_array_equal(left, views[0])
            np.testing.assert_array_equal(right, views[1])
        shifts = block_disparity(left[..., None] / 255.0, right[..., None] / 255.0, patch=32)
        medians[rotate] = float(np.median(shifts))
    assert medians["ccw"] > 0.3 and medians["cw"] < -0.3, medians


def test_raw_views_hand_their_own_light_to_the_output_modes(raw_pair, tiny_checkpoint,
                                                            monkeypatch):
    """Linear views are made light once: the brightness tie and the overshoot limit read the
    combined light the views had before they were encoded for the network, not the encoded
    views decoded again; the output is the same either way."""
    from dualpixel.inference import build_deblurrer
    from dualpixel.inference.encoding import deblur_encoded
    from dualpixel.optics import tone

    left, right = (v.astype(np.float32)[..., None] / 65535 for v in raw_pair)
    encoding = ViewEncoding("linear", BLACK, WHITE)
    deblurrer = build_deblurrer(tiny_checkpoint, device="cpu", precision="fp32",
                                brightness="tied", overshoot="limited")
    decodes = []
    original = tone.combined_light
    monkeypatch.setattr(tone, "combined_light",
                        lambda *a, **k: decodes.append(a[2] if len(a) > 2 else "srgb")
                        or original(*a, **k))
    own = deblur_encoded(deblurrer, left, right, encoding, scale=65535)
    assert decodes == []  # the light was handed over
    deblurrer.reset()
    again = deblur_encoded(lambda a, b: deblurrer(a, b), left, right, encoding, scale=65535)
    assert decodes == ["srgb"]  # a plain callable: the encoded views decoded once, as before
    np.testing.assert_allclose(own, again, atol=2e-6)
