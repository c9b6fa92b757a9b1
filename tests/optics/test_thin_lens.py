import numpy as np
import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.optics.thin_lens import (
    PAPER_LENS_SETS,
    ThinLens,
    coc_radius,
    focus_from_depth,
)


def test_eq1_by_hand():
    cam = ThinLens(focal_length=10.0, f_number=2.0, focus_distance=30.0, pixel_pitch=0.25,
                   max_coc_radius=1e9)
    d = 50.0
    s_prime = 10.0 * 30.0 / (30.0 - 10.0)
    expected = (10.0 / 2.0) / 2.0 * s_prime / 30.0 * (d - 30.0) / d / 0.25
    assert float(coc_radius(np.array([d]), cam)[0]) == pytest.approx(expected)


def test_sign_convention_and_clamp_numpy_and_torch():
    cam = PAPER_LENS_SETS["set2"]
    depth = np.array([0.5, 4.0, 8.0, 20.0, 1e6])
    r_np = coc_radius(depth, cam)
    r_t = coc_radius(torch.tensor(depth), cam)
    assert isinstance(r_t, torch.Tensor) and r_t.dtype == torch.float64
    np.testing.assert_allclose(r_np, r_t.numpy())
    assert r_np[0] == -40.0  # clamped in front
    assert r_np[1] < 0 and r_np[2] == 0 and r_np[3] > 0
    assert np.all(np.diff(r_np) > 0)  # monotone in depth: larger r is farther away
    assert r_np[4] == pytest.approx(cam.coc_scale, rel=1e-5)


def test_presets_match_the_paper():
    sets = [(c.focal_length, c.f_number, c.focus_distance) for c in PAPER_LENS_SETS.values()]
    assert sets == [(4, 5, 6), (5, 8, 6), (7, 5, 8), (10, 13, 12), (22, 10, 30)]
    assert all(c.max_coc_radius == 40 for c in PAPER_LENS_SETS.values())


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"f_number": 0.0}, r"f_number must be in \(0"),
     ({"focus_distance": 3.0}, "focus_distance must be greater than focal_length"),
     ({"pixel_pitch": -1.0}, r"pixel_pitch must be in \(0")],
)
def test_bad_camera_parameters(kwargs, message):
    base = {"focal_length": 4.0, "f_number": 5.0, "focus_distance": 6.0}
    with pytest.raises(ParameterError, match=message):
        ThinLens(**{**base, **kwargs})


@pytest.mark.parametrize(("value", "message"), [(np.nan, "NaN"), (-1.0, "negative"),
                                                (np.inf, "infinite"), (0.0, "zero")])
def test_bad_depth(value, message):
    depth = np.full((4, 4), 5.0)
    depth[1, 2] = value
    with pytest.raises(ParameterError, match=message):
        coc_radius(depth, PAPER_LENS_SETS["set0"])


def test_profiles_focus_at_one_depth_percentile():
    depth = np.linspace(1.0, 11.0, 101)
    assert focus_from_depth(depth) == pytest.approx(4.0)  # the 30th percentile by default
    assert focus_from_depth(depth, 50) == pytest.approx(6.0)
    with pytest.raises(ParameterError, match="percentile must be in"):
        focus_from_depth(depth, 120)


def test_the_old_names_of_lenses_still_work_with_a_warning():
    """"Camera" names a calibrated camera file alone; a lens set's thin lens had that name
    until release 0.2, and the old spellings answer, with a dated warning, until 0.3."""
    import dualpixel.optics as optics
    from dualpixel.optics import thin_lens
    from dualpixel.synthesis.frame import draw_sequence

    with pytest.warns(FutureWarning, match="ThinLens; the old name goes in release 0.3"):
        assert optics.ThinLensCamera is thin_lens.ThinLens
    with pytest.warns(FutureWarning, match="PAPER_LENS_SETS"):
        assert thin_lens.CAMERA_PRESETS is thin_lens.PAPER_LENS_SETS
    profile = thin_lens.DEFOCUS_PROFILES["dslr-840"]
    with pytest.warns(FutureWarning, match=r"DefocusProfile\.lens\(\)"):
        old = profile.camera(np.random.default_rng(1), 2.0, 840)
    assert old == profile.lens(np.random.default_rng(1), 2.0, 840)
    draw = draw_sequence(0, "set1")
    with pytest.warns(FutureWarning, match=r"SequenceDraw\.lens"):
        assert draw.camera is draw.lens is thin_lens.PAPER_LENS_SETS["set1"]
    assert draw.describe()["camera"]["name"] == "set1"  # manifests keep their key
    from dualpixel.synthesis.frame import SequenceDraw

    with pytest.warns(FutureWarning, match=r"SequenceDraw\(lens=\.\.\.\)"):
        again = SequenceDraw(camera=draw.lens, psf=draw.psf, distortion=draw.distortion,
                             noise_sigma=draw.noise_sigma)
    assert again == draw
    with pytest.raises(AttributeError):
        optics.NoSuchLens  # noqa: B018
