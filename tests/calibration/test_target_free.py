"""A camera from its DP views alone (dualpixel.calibration.target_free) and the command."""

import json

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.calibration.camera import view_kernels
from dualpixel.calibration.target_free import (
    RATIO_GRID,
    blocks_at_ratios,
    calibrate_camera_from_views,
    view_energies,
)
from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.io.images import write_png
from tests.calibration.test_camera import OTHER_PSF, RATIO, TRUE_PSF, _pair, _texture

RADII = np.arange(1.0, 9.01, 0.5)


def _convolved(radius: float, ratio: float, size: int = 224):
    """Views of a texture blurred by exactly our kernels at one radius, mixed by ``ratio``."""
    sharp = _texture(size, size, 5)
    k_left, k_right = view_kernels(radius, TRUE_PSF)
    left, right = (cv2.filter2D(sharp, -1, k, borderType=cv2.BORDER_REFLECT)
                   for k in (k_left, k_right))
    return ((1 + ratio) / 2 * left + (1 - ratio) / 2 * right,
            (1 + ratio) / 2 * right + (1 - ratio) / 2 * left)


def _noisy(view: np.ndarray, rng: np.random.Generator, sigma: float) -> np.ndarray:
    """Gaussian noise, then 8-bit coding."""
    return np.round(np.clip(view + rng.normal(0.0, sigma, view.shape), 0, 1) * 255) / 255


def test_energy_is_least_at_the_kernels_and_ratio_that_made_the_views():
    left, right = _convolved(5.0, 0.8)
    energies = view_energies(left, right, TRUE_PSF, RADII, RATIO_GRID, patch=48)
    share = energies.energy / energies.reference[:, None, None, None]
    flat = share.reshape(3, -1, *share.shape[-2:]).mean(axis=0)  # (R * 2 * A, rows, cols)
    best = np.unravel_index(flat.argmin(axis=0), share.shape[1:4])
    assert np.all(RADII[best[0]] == 5.0)
    assert np.all(RATIO_GRID[best[2]] == pytest.approx(0.8))
    assert flat.min() < 1e-3  # the views explain each other at the truth
    # the other side of the focal plane (the same kernels mirrored) does not
    assert share[:, RADII.tolist().index(5.0), 1, best[2][0, 0]].min() > 0.5


def test_a_known_ratio_gives_the_blur_and_another_trades_radius_for_it():
    """At the ratio that made the views every block reads the true radius; a larger ratio
    reads a smaller blur (the views fix the disparity, the ratio and radius's product)."""
    left, right = _convolved(5.0, 0.8)
    energies = view_energies(left, right, TRUE_PSF, RADII, RATIO_GRID, patch=48)
    right_ratio = blocks_at_ratios([energies], (0.8, 0.8, 0.8))
    assert right_ratio.informative[0].all() and (right_ratio.radius[0] == 5.0).all()
    larger = blocks_at_ratios([energies], (1.2, 1.2, 1.2))
    assert (larger.radius[0] < 5.0).all()
    with pytest.raises(ParameterError, match="one ratio per channel"):
        blocks_at_ratios([energies], (0.8,))


def test_noise_adds_the_same_to_every_candidate():
    """White noise alone: each candidate's energy per pixel is the noise's variance, whatever
    the radius and ratio, so noise does not pull the fit toward large radii or small ratios
    (the identity's plain residual shrinks with the kernels' energy)."""
    rng = np.random.default_rng(0)
    sigma = 0.05
    left, right = (rng.normal(0.5, sigma, (336, 336, 1)) for _ in range(2))
    energies = view_energies(left, right, TRUE_PSF, RADII, RATIO_GRID[::8], patch=48)
    per_pixel = energies.energy.mean(axis=(-2, -1))[0] / 48**2  # (R, 2, A)
    np.testing.assert_allclose(per_pixel, sigma**2, rtol=0.12)
    spread = per_pixel.max() / per_pixel.min()
    assert spread < 1.25, spread


@pytest.mark.parametrize(("light", "sigma"), [("encoded", 0.0), ("linear", 0.0),
                                              ("encoded", 0.01), ("linear", 0.01)])
def test_views_alone_recover_a_known_camera(light, sigma):
    """Pairs rendered with known ratios, blurred in linear light or the stored values, clean or
    noisy and 8-bit coded: the ratios within 0.06, where the blur happens, the PSF shape."""
    rng = np.random.default_rng(1)
    pairs = [(name, _noisy(left, rng, sigma), _noisy(right, rng, sigma)) if sigma
             else (name, left, right)
             for name, left, right, _ in (_pair(seed, light=light) for seed in (1, 2, 3))]
    candidates = (TRUE_PSF, OTHER_PSF) if sigma else (TRUE_PSF,)
    result = calibrate_camera_from_views(pairs, patch=32, max_radius=10.0,
                                         psf_candidates=candidates)
    np.testing.assert_allclose(result.camera.disparity_ratio, RATIO, atol=0.06)
    assert result.camera.light == light
    assert result.camera.psf == TRUE_PSF
    assert result.camera.blocks >= 30 and result.camera.width == 288
    # the plane (1.3 to 8 m, focused at 2 m) lies behind the focal plane beyond x = 30 px:
    # every informative block there on one side
    sides = np.concatenate([side[informative & (centres[..., 0] > 30 + 32)]
                            for side, informative, centres in zip(
                                result.fit.side, result.fit.informative, result.centres)])
    assert sides.size >= 30 and (sides == sides[0]).all()


def test_grey_views_give_one_ratio_for_every_channel():
    pairs = [(name, left[..., 1], right[..., 1])
             for name, left, right, _ in (_pair(seed) for seed in (1, 2))]
    camera = calibrate_camera_from_views(pairs, patch=32, max_radius=10.0).camera
    assert len(set(camera.disparity_ratio)) == 1
    assert camera.disparity_ratio[0] == pytest.approx(RATIO[1], abs=0.06)


def test_bad_pairs_are_named():
    name, left, right, _ = _pair(1)
    with pytest.raises(ParameterError, match="odd: left and right views differ"):
        calibrate_camera_from_views([("odd", left, right[:-8])])
    with pytest.raises(ParameterError, match="grey: 1 channels where pair1 has 3"):
        calibrate_camera_from_views([(name, left, right), ("grey", left[..., 0], right[..., 0])])
    flat = np.full_like(left, 0.5)
    with pytest.raises(ParameterError, match=r"too few informative blocks: 0 .*flat 0"):
        calibrate_camera_from_views([("flat", flat, flat)], patch=32, max_radius=10.0)
    with pytest.warns(UserWarning, match="flat: no informative block"):
        calibrate_camera_from_views([(name, left, right), _pair(2)[:3], ("flat", flat, flat)],
                                    patch=32, max_radius=10.0)
    with pytest.raises(ParameterError, match="light must be"):
        calibrate_camera_from_views([(name, left, right)], light="log")


def test_a_pair_of_another_camera_is_named():
    size = (256, 448)
    pairs = [_pair(seed, size=size)[:3] for seed in (1, 2, 3)]
    pairs.append(_pair(4, ratio=(1.3, 1.3, 1.3), size=size)[:3])
    with pytest.warns(UserWarning, match=r"1 pair\(s\) disagree.*pair4"):
        calibrate_camera_from_views(pairs, patch=32, max_radius=10.0)


def _write_scenes(root, targets: bool):
    for seed in (1, 2, 3):
        name, left, right, target = _pair(seed)
        folder = root / name
        folder.mkdir(parents=True)
        write_png(folder / "view0.png", left, bit_depth=8)
        write_png(folder / "view1.png", right, bit_depth=8)
        if targets:
            write_png(folder / "target.png", target, bit_depth=8)


def test_command_calibrates_from_views_alone(tmp_path):
    _write_scenes(tmp_path / "pairs", targets=False)
    output = tmp_path / "camera.json"
    result = CliRunner().invoke(cli, ["calibrate", "camera", "--input", str(tmp_path / "pairs"),
                                      "--output", str(output), "--patch", "32",
                                      "--max-radius", "10", "--figure",
                                      str(tmp_path / "views.png")])
    assert result.exit_code == 0, result.output
    assert "from the views alone (3 pairs)" in result.output
    camera = json.loads(output.read_text())
    np.testing.assert_allclose(camera["disparity_ratio"], RATIO, atol=0.06)
    assert cv2.imread(str(tmp_path / "views.png")).shape[1] > 500


def test_command_refuses_pairs_mixing_targets_and_none(tmp_path):
    root = tmp_path / "pairs"
    _write_scenes(root, targets=True)
    (root / "pair2" / "target.png").unlink()
    result = CliRunner().invoke(cli, ["calibrate", "camera", "--input", str(root), "--output",
                                      str(tmp_path / "camera.json"), "--patch", "32",
                                      "--max-radius", "10"])
    assert result.exit_code != 0
    assert "pair2" in result.output and "--ignore-targets" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "camera.json").exists()
    result = CliRunner().invoke(cli, ["calibrate", "camera", "--input", str(root), "--output",
                                      str(tmp_path / "camera.json"), "--patch", "32",
                                      "--max-radius", "10", "--ignore-targets"])
    assert result.exit_code == 0, result.output
    assert "targets unread" in result.output


def test_a_ratio_at_the_end_of_the_search_is_reported_unmeasured():
    """At a low ratio (0.45) the views of our own kernels trade disparity for blur up to the
    search's end (1.5): the calibration says so rather than passing the ratio off as measured."""
    pairs = [(f"p{i}", *_convolved(3.0 + i, 0.45)) for i in range(3)]
    with pytest.warns(UserWarning, match="R, G, B ran to the end of the search"):
        result = calibrate_camera_from_views(pairs, light="encoded")
    assert result.unmeasured == ("R", "G", "B")
    assert calibrate_camera_from_views([(f"p{i}", *_convolved(4.0, 0.8)) for i in range(3)],
                                       light="encoded").unmeasured == ()
