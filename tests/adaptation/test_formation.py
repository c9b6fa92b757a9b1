"""Blur maps from a pair's views, the formation loss, the crops that feed it, and training with
it (dualpixel.adaptation)."""

import json

import cv2
import numpy as np
import pytest
import torch

from dualpixel.adaptation.blur_maps import blur_maps
from dualpixel.calibration.camera import view_kernels
from dualpixel.data.views import ViewsDataset, read_blur_maps, write_blur_maps
from dualpixel.errors import InputFileError
from dualpixel.io.images import write_png
from dualpixel.optics.camera import DPCamera
from dualpixel.training.formation import FormationLoss
from tests.calibration.test_camera import TRUE_PSF, _texture

CAMERA = DPCamera(name="test", width=224, disparity_ratio=(0.6, 0.85, 0.75), psf=TRUE_PSF)


def _views(sharp: np.ndarray, radius: float, camera: DPCamera = CAMERA, side: int = 1):
    """The camera's views of ``sharp`` at one radius (its formation, in stored values)."""
    k_left, k_right = view_kernels(radius, camera.psf)
    if side < 0:
        k_left, k_right = k_right, k_left
    own, other = (cv2.filter2D(sharp, -1, k, borderType=cv2.BORDER_REFLECT)
                  for k in (k_left, k_right))
    a = np.asarray(camera.disparity_ratio, np.float32)
    return (1 + a) / 2 * own + (1 - a) / 2 * other, (1 + a) / 2 * other + (1 - a) / 2 * own


def _item(left, right, radius, side=1.0, blurred=1.0, in_focus=0.0):
    size = left.shape[:2]

    def tensor(view):
        return torch.from_numpy(np.ascontiguousarray(view)).permute(2, 0, 1)[None]

    return {"left": tensor(left), "right": tensor(right),
            "radius": torch.full((1, *size), float(radius)),
            "side": torch.full((1, *size), float(side)),
            "blurred": torch.full((1, *size), float(blurred)),
            "in_focus": torch.full((1, *size), float(in_focus))}


def _as_output(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1)[None]


@pytest.mark.parametrize("side", [1, -1])
def test_the_sharp_image_explains_its_views_and_the_blurred_one_does_not(side):
    sharp = _texture(128, 128, 3)
    left, right = _views(sharp, 5.0, side=side)
    loss = FormationLoss(CAMERA)
    truth, parts = loss(_as_output(sharp), _item(left, right, 5.0, side))
    assert float(truth) < 1e-8 and set(parts) == {"formation"}
    blurred, _ = loss(_as_output((left + right) / 2), _item(left, right, 5.0, side))
    assert float(blurred) > 1e4 * float(truth) + 1e-4
    wrong_side, _ = loss(_as_output(sharp), _item(left, right, 5.0, -side))
    wrong_radius, _ = loss(_as_output(sharp), _item(left, right, 3.0, side))
    assert min(float(wrong_side), float(wrong_radius)) > 1e-4
    # its gradient leads a blurred guess toward the sharp image
    guess = _as_output((left + right) / 2).requires_grad_(True)
    value, _ = loss(guess, _item(left, right, 5.0, side))
    value.backward()
    rate = 0.1 * float(value.detach()) / float((guess.grad**2).sum())  # a tenth of the drop
    step = guess.detach() - rate * guess.grad
    assert float(loss(step, _item(left, right, 5.0, side))[0]) < 0.95 * float(value.detach())


def test_linear_light_cameras_blur_in_linear_light():
    from dualpixel.optics.tone import linear_to_srgb_array, srgb_to_linear_array

    linear = DPCamera(name="lin", width=224, disparity_ratio=(0.8, 0.8, 0.8), psf=TRUE_PSF,
                      light="linear")
    sharp = _texture(128, 128, 4)
    left, right = (linear_to_srgb_array(v) for v in _views(srgb_to_linear_array(sharp), 4.0,
                                                              linear))
    item = _item(left.astype(np.float32), right.astype(np.float32), 4.0)
    in_linear = float(FormationLoss(linear)(_as_output(sharp), item)[0])
    as_stored = float(FormationLoss(DPCamera(**{**linear.__dict__, "light": "encoded"}))(
        _as_output(sharp), item)[0])
    assert in_linear < 1e-7 < as_stored


def test_in_focus_blocks_must_keep_the_views_and_the_log_form_is_in_decibels():
    sharp = _texture(96, 96, 5)
    item = _item(sharp, sharp, 0.5, blurred=0.0, in_focus=1.0)
    loss = FormationLoss(CAMERA, reduction="log", in_focus_weight=2.0)
    same, parts = loss(_as_output(sharp), item)
    assert set(parts) == {"in_focus"} and float(same) < -150  # 2 x 10 log10(1e-10 + 0)
    changed = _as_output(np.clip(sharp + 0.01, 0, 1))
    value, parts = loss(changed, item)
    expected = 10 * np.log10(float(((changed - _as_output(sharp)) ** 2)[..., 16:-16, 16:-16]
                                   .mean()))
    assert float(parts["in_focus"]) == pytest.approx(expected, abs=0.01)
    assert float(value) == pytest.approx(2 * expected, abs=0.02)


def _pairs_on_disk(tmp_path, radius=5.0, count=2):
    pairs = []
    for n in range(count):
        sharp = _texture(200, 260, 10 + n)
        left, right = _views(sharp, radius)
        folder = tmp_path / f"pair{n}"
        folder.mkdir()
        for name, view in (("left", left), ("right", right)):
            write_png(folder / f"{name}.png", np.clip(view, 0, 1), bit_depth=16)
        pairs.append((str(folder / "left.png"), str(folder / "right.png"), left, right))
    return pairs


def test_blur_maps_read_the_blur_that_made_the_views_and_round_trip(tmp_path):
    pairs = _pairs_on_disk(tmp_path)
    maps = blur_maps(pairs, CAMERA)
    for blur in maps:
        chosen = blur.informative
        assert chosen.mean() > 0.8
        assert np.abs(blur.radius[chosen] - 5.0).max() <= 0.5
        assert (blur.side[chosen] == 1).all() and not blur.in_focus.any()
    path = write_blur_maps(maps, CAMERA, tmp_path / "views.json")
    again, camera = read_blur_maps(path)
    assert camera == CAMERA
    assert np.array_equal(again[0].informative, maps[0].informative)
    np.testing.assert_allclose(again[0].radius, maps[0].radius, atol=1e-3)
    # identical views (nothing defocused) of texture: in focus
    sharp = _texture(200, 260, 20)
    in_focus = blur_maps([("l", "r", sharp, sharp.copy())], CAMERA)[0]
    assert in_focus.in_focus.mean() > 0.8 and not in_focus.informative.any()
    record = json.loads(path.read_text())
    record["pairs"][0]["side"] = [[1]]
    path.write_text(json.dumps(record))
    with pytest.raises(InputFileError, match=r"views\.json.*one shape"):
        read_blur_maps(path)


def test_crops_carry_their_blocks_maps_and_flips_keep_the_formation(tmp_path):
    pairs = _pairs_on_disk(tmp_path)
    blur = blur_maps(pairs, CAMERA)[0]
    height, width = pairs[0][2].shape[:2]
    radius, _, blurred, _ = blur.pixel_maps(height, width)
    top = blur.margin
    assert radius[top, top] == blur.radius[0, 0] and radius[0, 0] == 0 and blurred[0, 0] == 0
    dataset = ViewsDataset([blur], 128, flips=True)
    for seed in range(4):
        item = dataset[(0, seed)]
        assert item["left"].shape == (1, 3, 128, 128) and item["radius"].shape == (1, 128, 128)
        chosen = item["blurred"][0] > 0  # crops are drawn where blocks are labelled
        assert chosen.float().mean() > 0.1
        assert torch.all((item["radius"][0][chosen] - 5.0).abs() <= 0.5)
    assert dataset[(0, 7)]["left"].equal(dataset[(0, 7)]["left"])  # fixed by the seed
    with pytest.raises(InputFileError, match="smaller than the 512-px crops"):
        ViewsDataset([blur], 512)


def test_flips_keep_each_blocks_side():
    """A horizontal flip mirrors the image and swaps the views: the flipped sharp image explains
    the flipped views at the same side."""
    from dualpixel.data.dataset import flip_horizontal

    sharp = _texture(96, 96, 6)
    left, right = _views(sharp, 4.0, side=1)
    item = flip_horizontal({**_item(left, right, 4.0), "sharp": _as_output(sharp)})
    value, _ = FormationLoss(CAMERA)(item.pop("sharp"), item)
    assert float(value) < 1e-8


def test_training_with_the_views_resumes_to_the_same_weights(tiny_synthetic_dataset, tmp_path):
    from dualpixel.models import load_model
    from dualpixel.training import train
    from tests.training.test_trainer import tiny_config

    pairs = _pairs_on_disk(tmp_path, count=2)
    path = write_blur_maps(blur_maps(pairs, CAMERA), CAMERA, tmp_path / "views.json")
    config = tiny_config(tiny_synthetic_dataset, views_data=str(path), views_batch=2,
                         threads=1, lr_halve_every=1, patch_size=64)
    straight = train(config, tmp_path / "straight", progress=False)
    assert all("formation" in record for record in straight.history)
    one = tiny_config(tiny_synthetic_dataset, views_data=str(path), views_batch=2, threads=1,
                      lr_halve_every=1, epochs=1, patch_size=64)
    train(one, tmp_path / "resumed", progress=False)
    train(config, tmp_path / "resumed", resume=True, progress=False)
    a = load_model(tmp_path / "straight" / "last.safetensors").state_dict()
    b = load_model(tmp_path / "resumed" / "last.safetensors").state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)


def test_a_camera_measured_from_the_pairs_gives_their_maps_without_a_second_pass(tmp_path):
    from dualpixel.adaptation.blur_maps import maps_from_fit
    from dualpixel.calibration.target_free import calibrate_camera_from_views

    pairs = []
    for n in range(3):
        sharp = _texture(256, 352, 40 + n)
        left, right = _views(sharp, 4.0 + n)
        pairs.append((f"p{n}/left.png", f"p{n}/right.png", left, right))
    measured = calibrate_camera_from_views([(lp, left, right) for lp, _, left, right in pairs],
                                           light="encoded")
    assert np.allclose(measured.camera.disparity_ratio, CAMERA.disparity_ratio, atol=0.05)
    reused = maps_from_fit(pairs, measured.fit, measured.centres, patch=48)
    again = blur_maps(pairs, measured.camera)
    for a, b, n in zip(reused, again, range(3)):
        assert np.array_equal(a.informative, b.informative) and a.margin == b.margin
        assert np.array_equal(a.radius, b.radius) and np.array_equal(a.side, b.side)
        assert np.abs(a.radius[a.informative] - (4.0 + n)).max() <= 0.5
