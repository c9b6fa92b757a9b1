import cv2
import numpy as np
import pytest
from click.testing import CliRunner

import dualpixel
from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.inference.frame_fusion import FrameFusion, check_fuse_frames

SIZE = (96, 128)  # rows, columns


def scene(seed: int = 0) -> np.ndarray:
    """A textured colour image larger than the frames, so a camera pan can crop it."""
    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.random((SIZE[0] + 40, SIZE[1] + 40, 3)).astype(np.float32),
                               (0, 0), 2.0)
    return 0.2 + 0.6 * (texture - texture.min()) / np.ptp(texture)


def pan(image: np.ndarray, k: int) -> np.ndarray:
    """Frame ``k`` of a pan: the window moved 3 px right and 1 px down a frame."""
    return image[k : k + SIZE[0], 3 * k : 3 * k + SIZE[1]].copy()


def noisy_pan(frames: int, sigma: float = 0.03, seed: int = 1):
    rng = np.random.default_rng(seed)
    image = scene()
    clean = [pan(image, k) for k in range(frames)]
    views = [(c + rng.normal(0, sigma, c.shape).astype(np.float32),
              c + rng.normal(0, sigma, c.shape).astype(np.float32)) for c in clean]
    return clean, views


def interior_mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a[12:-12, 12:-12] - b[12:-12, 12:-12]) ** 2))


def test_registered_frames_average_the_noise_away():
    """A pan with new noise every frame: each view of the fourth frame, averaged with the three
    earlier ones registered onto it, has well under half the noise power (a quarter is the
    ideal); the first frame comes out as it went in."""
    clean, views = noisy_pan(4)
    fusion = FrameFusion(4)
    fused = [fusion(*pair) for pair in views]
    assert np.array_equal(fused[0][0], views[0][0]) and np.array_equal(fused[0][1], views[0][1])
    for side in (0, 1):
        before = interior_mse(views[3][side], clean[3])
        after = interior_mse(fused[3][side], clean[3])
        assert after < 0.45 * before, (side, before, after)
    # more earlier frames, less noise: the second frame has one to average with
    assert interior_mse(fused[1][0], clean[1]) < 0.7 * interior_mse(views[1][0], clean[1])


@pytest.mark.parametrize("sigma", [0.008, 0.06])
def test_the_match_follows_each_sequences_own_noise(sigma):
    """A clean and a very noisy pan are both averaged (the fourth frame's noise power well
    under half): the match level is a number of spreads of each frame's own difference, so
    the noisy frames are not taken for mismatches, nor the clean ones matched loosely."""
    clean, views = noisy_pan(4, sigma=sigma, seed=5)
    fusion = FrameFusion(4)
    fused = [fusion(*pair) for pair in views][3]
    for side in (0, 1):
        before = interior_mse(views[3][side], clean[3])
        assert interior_mse(fused[side], clean[3]) < 0.45 * before, side


def test_a_moving_object_leaves_no_ghost():
    """A bright square jumps 20 px a frame over a still background (no noise): where it was
    and where it is, the fused frame stays the current frame, while a plain average of the
    frames would show the square's earlier places."""
    background = scene(2)[: SIZE[0], : SIZE[1]]
    frames = []
    for k in range(3):
        image = background.copy()
        image[30:60, 10 + 20 * k : 40 + 20 * k] = 0.98
        frames.append(image)
    fusion = FrameFusion(3)
    for image in frames:
        fused, _ = fusion(image, image)
    ghost = np.abs(fused - frames[2]).max()
    plain = np.abs(np.mean(frames, axis=0) - frames[2]).max()
    assert plain > 0.2 and ghost < 0.25 * plain, (ghost, plain)


def test_reset_forgets_the_earlier_frames_and_grey_views_work():
    _, views = noisy_pan(3)
    grey = [(left[..., 1], right[..., 1]) for left, right in views]
    fusion = FrameFusion(3)
    fusion(*grey[0])
    assert not np.array_equal(fusion(*grey[1])[0], grey[1][0])
    fusion.reset()
    left, right = fusion(*grey[2])
    assert left.shape == grey[2][0].shape and np.array_equal(left, grey[2][0])
    assert np.array_equal(right, grey[2][1])
    one = FrameFusion(1)
    for pair in grey:
        assert np.array_equal(one(*pair)[0], pair[0])


def test_a_frame_of_another_size_mid_sequence_is_refused():
    fusion = FrameFusion(2)
    fusion(np.zeros((32, 48, 3), np.float32), None)
    with pytest.raises(ParameterError, match="48x32 in one sequence"):
        fusion(np.zeros((32, 40, 3), np.float32), None)


@pytest.mark.parametrize("frames", [0, -2, 1.5, True, "3"])
def test_a_frame_count_that_is_no_whole_number_of_at_least_one_is_refused(frames):
    with pytest.raises(ParameterError, match="fuse_frames"):
        check_fuse_frames(frames)


def test_the_api_fuses_only_the_frames_of_a_sequence():
    """``deblur(sequence=True, fuse_frames=3)`` runs the first frame as without fusion and the
    later ones on averaged views (closer to the noise-free frame's output); independent pairs
    are refused the option."""
    clean, views = noisy_pan(3)
    lefts, rights = (np.stack([pair[side] for pair in views]).clip(0, 1) for side in (0, 1))
    alone = dualpixel.deblur(lefts, rights, sequence=True, precision="fp32")
    fused = dualpixel.deblur(lefts, rights, sequence=True, fuse_frames=3, precision="fp32")
    reference = dualpixel.deblur(np.stack(clean), np.stack(clean), sequence=True,
                                 precision="fp32")
    assert np.array_equal(alone[0], fused[0])
    assert interior_mse(fused[2], reference[2]) < 0.6 * interior_mse(alone[2], reference[2])
    with pytest.raises(ParameterError, match="sequence=True"):
        dualpixel.deblur(lefts, rights, fuse_frames=3)


def test_the_commands_refuse_a_bad_frame_count(tmp_path):
    for command in ("deblur", "eval"):
        result = CliRunner().invoke(cli, [command, "--fuse-frames", "0", "-o",
                                          str(tmp_path / command)])
        assert result.exit_code == 2 and "--fuse-frames" in result.output
        assert "Traceback" not in result.output


def test_deblur_fuses_a_frame_folder_and_says_when_there_is_nothing_to_fuse(
        tiny_checkpoint, tiny_synthetic_dataset, tmp_path):
    left = tiny_synthetic_dataset / "train_l" / "source" / "seq_001"
    right = tiny_synthetic_dataset / "train_r" / "source" / "seq_001"
    outputs = {}
    for frames in (1, 3):
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(left), "--right", str(right), "--output",
            str(tmp_path / f"fuse{frames}"), "--checkpoint", str(tiny_checkpoint),
            "--fuse-frames", str(frames)])
        assert result.exit_code == 0, result.output
        assert "nothing to fuse" not in result.output
        outputs[frames] = [cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
                           for path in sorted((tmp_path / f"fuse{frames}").iterdir())]
    assert len(outputs[3]) == len(outputs[1]) >= 2
    assert np.array_equal(outputs[3][0], outputs[1][0])  # the first frame as without
    assert not np.array_equal(outputs[3][-1], outputs[1][-1])
    pair = sorted(left.iterdir())[0]
    result = CliRunner().invoke(cli, [
        "deblur", "--left", str(pair), "--right", str(right / pair.name), "--output",
        str(tmp_path / "pair.png"), "--checkpoint", str(tiny_checkpoint), "--fuse-frames", "3"])
    assert result.exit_code == 0 and "every input here is a single pair" in result.output


def test_the_video_preset_fuses_six_frames_of_a_sequence_and_nothing_of_single_pairs():
    """``rdpd-light-video`` is the default's weights with frame fusion: on a sequence it runs
    as ``fuse_frames=6`` does, on independent pairs as the default; a value given wins."""
    _, views = noisy_pan(3)
    lefts, rights = (np.stack([pair[side] for pair in views]).clip(0, 1) for side in (0, 1))
    common = {"precision": "fp32", "device": "cpu"}
    preset = dualpixel.deblur(lefts, rights, model="rdpd-light-video", sequence=True, **common)
    fused = dualpixel.deblur(lefts, rights, model="rdpd-light.v18", sequence=True,
                             fuse_frames=6, **common)
    alone = dualpixel.deblur(lefts, rights, model="rdpd-light.v18", sequence=True, **common)
    assert np.array_equal(preset, fused)
    assert not np.array_equal(preset[-1], alone[-1])
    told = dualpixel.deblur(lefts, rights, model="rdpd-light-video", sequence=True,
                            fuse_frames=1, **common)
    assert np.array_equal(told, alone)
    pairs = dualpixel.deblur(lefts, rights, model="rdpd-light-video", **common)
    assert np.array_equal(pairs, dualpixel.deblur(lefts, rights, model="rdpd-light.v18",
                                                  **common))


def test_eval_reports_the_frames_a_preset_fuses(tiny_synthetic_dataset, tmp_path):
    """``eval --checkpoint rdpd-light-video`` runs with the preset's fusion and says so in its
    report; ``--fuse-frames 1`` turns it off."""
    import json

    for option, frames in (([], 6), (["--fuse-frames", "1"], 1)):
        out = tmp_path / f"eval{frames}"
        result = CliRunner().invoke(cli, [
            "eval", "--dataset", str(tiny_synthetic_dataset), "--split", "train",
            "--checkpoint", "rdpd-light-video", "--device", "cpu", "--no-niqe",
            "--figures", "0", "-o", str(out), *option])
        assert result.exit_code == 0, result.output
        report = json.loads((out / "summary.json").read_text())
        assert report["fuse_frames"] == frames and report["checkpoint"] == "rdpd-light-video"
        assert ("+fuse6" in result.output) == (frames == 6)
