import json

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from scipy.signal import fftconvolve

from dualpixel.calibration import (
    DiskGrid,
    SearchGrid,
    disk_grid_pattern,
    estimate_psfs,
    fit_distortion,
    fit_psf_models,
    locate_disks,
    psf_correlation,
    square_grid_pattern,
)
from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.optics.distortion import DISTORTION_PRESETS, distort_image, distort_points
from dualpixel.optics.psf import PSFParams, dp_psf


def test_patterns_have_the_requested_geometry():
    grid = DiskGrid(320, 256, 64, 0.1)
    image = disk_grid_pattern(grid)
    found = locate_disks(image)
    np.testing.assert_allclose(found, grid.centres(), atol=0.05)
    # the anti-aliased area of each disk is pi r^2
    assert image.sum() / len(found) == pytest.approx(np.pi * grid.radius**2, rel=0.01)
    squares = square_grid_pattern(200, 100, square=10, spacing=20)
    assert squares.shape == (100, 200) and squares.mean() == pytest.approx(0.75, abs=0.01)


@pytest.mark.parametrize("model", ["ours", "disk"])
def test_psf_estimation_recovers_a_known_psf(model):
    grid = DiskGrid(384, 256, 64, 0.1)
    pattern = disk_grid_pattern(grid)
    kernels = dp_psf(6.0, PSFParams(n=6, alpha=0.6, beta=0.3), model=model, size=21)
    truth = {"left": 2 * kernels.left.numpy(), "combined": kernels.combined.numpy()}
    rng = np.random.default_rng(0)
    views = {  # half-brightness DP views, display black level, sensor noise
        "left": 0.5 * fftconvolve(pattern, truth["left"], "same"),
        "combined": fftconvolve(pattern, truth["combined"], "same"),
    }
    views = {k: v + 0.05 + rng.normal(0, 0.001, v.shape) for k, v in views.items()}
    estimate = estimate_psfs(views, radius=grid.radius, kernel_size=21)
    assert len(estimate.centres) == len(grid.centres())
    for view, kernel in truth.items():
        scores = [psf_correlation(e, kernel) for e in estimate.psfs[view]]
        assert np.mean(scores) > 0.95, (view, np.mean(scores))
    # the left view keeps its displacement relative to the combined one (DP disparity)
    axis = np.arange(21) - 10
    centroid = lambda k: (k.sum(0) * axis).sum() / k.sum()  # noqa: E731
    assert centroid(estimate.psfs["left"][0]) == pytest.approx(centroid(truth["left"]), abs=0.3)


def test_parametric_fit_recovers_our_parameters():
    params = PSFParams(n=6, alpha=0.6, beta=0.3, kappa=0.21)
    kernels = dp_psf(np.array([7.0, -9.5]), params, size=41, dtype=torch.float64)
    grid = SearchGrid(n=(3.0, 6.0, 9.0), alpha=(0.4, 0.6, 0.8), beta=(0.2, 0.3, 0.4),
                      kappa=(0.14, 0.21, 0.28))
    fits = fit_psf_models(2 * kernels.left.numpy(), 2 * kernels.right.numpy(), grid=grid,
                          progress=False)
    assert len(fits) == 4
    for fit, radius in zip(fits, (7.0, 7.0, -9.5, -9.5)):
        assert (fit.n, fit.alpha, fit.beta, fit.kappa) == (6.0, 0.6, 0.3, 0.21)
        assert fit.radius == pytest.approx(radius)
        assert fit.correlation > 0.999
        assert fit.punnappurath_correlation < fit.correlation


def test_distortion_fit_recovers_known_coefficients():
    pattern = square_grid_pattern(240, 180, square=8, spacing=16)
    corners = torch.tensor([[0.0, 0.0], [239.0, 179.0], [120.0, 0.0], [0.0, 90.0]],
                           dtype=torch.float64)
    rng = np.random.default_rng(0)
    for name in ("set0", "set3"):
        truth = DISTORTION_PRESETS[name]
        capture = distort_image(torch.from_numpy(pattern)[None], truth)[0].numpy()
        capture = capture + rng.normal(0, 0.02, capture.shape).astype(np.float32)
        fit = fit_distortion(capture, pattern, working_width=240, levels=5)
        moved = distort_points(corners, fit.distortion, 240, 180)
        expected = distort_points(corners, truth, 240, 180)
        assert float((moved - expected).norm(dim=-1).max()) < 0.5, (name, fit)
        assert fit.correlation > 0.98


def test_fit_psf_command_on_real_pixel4_psfs(shared_dir, tmp_path):
    """A subset of the real Pixel 4 PSFs with the bank's values; the full run is in benchmarks/."""
    folder = shared_dir / "data" / "pixel4-measured-psf"
    result = CliRunner().invoke(cli, [
        "calibrate", "fit-psf", "--left", str(folder / "left.npy"), "--right",
        str(folder / "right.npy"), "--report", str(tmp_path), "--limit", "2", "--grid", "bank"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "summary.json").read_text())
    rows = (tmp_path / "fits.csv").read_text().splitlines()
    assert summary["kernels"] == 4 and len(rows) == 5
    header = rows[0].split(",")
    column = {name: [float(r.split(",")[header.index(name)]) for r in rows[1:]]
              for name in ("correlation", "punnappurath_correlation")}
    assert summary["mean_correlation_ours"] == pytest.approx(np.mean(column["correlation"]))
    assert summary["mean_correlation_punnappurath"] == pytest.approx(
        np.mean(column["punnappurath_correlation"]))
    # the paper's Fig. 5 finding on these kernels: our PSF model fits them better than theirs
    assert summary["ours_better_count"] == sum(
        a > b for a, b in zip(column["correlation"], column["punnappurath_correlation"]))
    assert summary["mean_correlation_ours"] > summary["mean_correlation_punnappurath"]
    assert (tmp_path / "figure.png").stat().st_size > 10_000
    bad = CliRunner().invoke(cli, ["calibrate", "fit-psf", "--left", str(folder / "left.npy"),
                                   "--right", str(tmp_path / "summary.json"), "--report",
                                   str(tmp_path / "x")])
    assert bad.exit_code == 1 and "summary.json" in bad.output


def test_pattern_command(tmp_path):
    out = tmp_path / "disks.png"
    result = CliRunner().invoke(cli, ["pattern", "--kind", "disks", "--size", "640x360",
                                      "--spacing", "40", "--output", str(out)])
    assert result.exit_code == 0 and "disks of radius 4" in result.output
    from dualpixel.io.images import read_rgb

    assert read_rgb(out).shape == (360, 640, 3)


def test_fit_psf_writes_a_camera_file_synthesis_takes(shared_dir, tmp_path):
    """The shipped Pixel 4 camera is made this way (there with the full grid)."""
    from dualpixel.calibration.camera import load_camera

    folder = shared_dir / "data" / "pixel4-measured-psf"
    args = ["calibrate", "fit-psf", "--left", str(folder / "left.npy"), "--right",
            str(folder / "right.npy"), "-o", str(tmp_path / "fit"), "--limit", "3", "--grid",
            "bank", "--camera", str(tmp_path / "phone.json")]
    missing = CliRunner().invoke(cli, args)
    assert missing.exit_code == 2 and "--camera-width" in missing.output
    result = CliRunner().invoke(cli, [*args, "--camera-width", "2016", "--camera-name", "p4"])
    assert result.exit_code == 0, result.output
    camera = load_camera(tmp_path / "phone.json")
    assert camera.name == "p4" and camera.width == 2016 and camera.light == "linear"
    assert camera.disparity_ratio == (1.0, 1.0, 1.0) and camera.blocks == 6
    radii = [float(r.split(",")[6]) for r in
             (tmp_path / "fit" / "fits.csv").read_text().splitlines()[1:]]
    assert camera.coc_percentiles["p50"] == pytest.approx(np.median(radii), abs=0.01)


def test_the_shipped_pixel4_camera_matches_its_measured_psfs():
    from dualpixel.calibration.camera import load_camera

    camera = load_camera("pixel4")
    assert camera.light == "linear" and camera.width == 2016
    assert 9 <= camera.coc_percentiles["p50"] <= 11  # the measured kernels' 10-px radius


def test_disk_location_takes_one_row_and_refuses_a_capture_without_disks():
    """One row of disks has no row spacing to measure, and dim specks are no disks: neither
    may end in NumPy warnings or an index error."""
    import warnings

    grid = DiskGrid(320, 64, 64, 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = locate_disks(disk_grid_pattern(grid))
    np.testing.assert_allclose(found, grid.centres(), atol=0.05)
    specks = np.zeros((64, 96))
    specks[10, 10] = specks[40, 50] = 1.0  # single pixels: below the smallest disk area
    with pytest.raises(ParameterError, match="no disks"):
        locate_disks(specks)
