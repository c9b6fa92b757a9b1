"""Training data like real DP photographs: photo-layout scenes, textures, defocus profiles, the
Pixel 4 PSF bank, and a dataset written with them."""

import json

import numpy as np
import pytest

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.lock import LOCK_NAME
from dualpixel.optics import DEFOCUS_PROFILES, PIXEL4_PSF_BANK, DefocusProfile, coc_radius
from dualpixel.synthesis import textures
from dualpixel.synthesis.dataset import SynthConfig, plan_jobs, read_manifest, synthesize_dataset
from dualpixel.synthesis.inputs import discover_sequences
from dualpixel.synthesis.scenes import SceneConfig, render_scene, write_scene_folder
from dualpixel.synthesis.textures import (
    PHOTOGRAPH_NAMES,
    photograph_path,
    photographs,
    random_texture,
)


def test_textures_are_varied_reproducible_and_in_range():
    assert len(photographs()) == len(PHOTOGRAPH_NAMES) == 15
    textures = [random_texture(np.random.default_rng(s), 48, 64) for s in range(12)]
    for t in textures:
        assert t.shape == (48, 64, 3) and t.dtype == np.float32
        assert 0 <= t.min() and t.max() <= 1
    assert np.array_equal(textures[3], random_texture(np.random.default_rng(3), 48, 64))
    means = [float(t.mean()) for t in textures]
    assert np.std(means) > 0.03


def test_textures_come_from_the_package_alone(monkeypatch):
    """Synthesis reads no other package's data: with scikit-image's and matplotlib's data
    unimportable, the photographs load and a texture is the same as before."""
    before = random_texture(np.random.default_rng(5), 40, 56)
    for module in ("skimage", "skimage.data", "matplotlib"):
        monkeypatch.setitem(__import__("sys").modules, module, None)
    textures.photographs.cache_clear()
    try:
        assert len(photographs()) == 15
        assert np.array_equal(random_texture(np.random.default_rng(5), 40, 56), before)
    finally:
        textures.photographs.cache_clear()


def test_every_shipped_photograph_has_its_licence_stated():
    folder = photograph_path(PHOTOGRAPH_NAMES[0]).parent
    table = (folder / "SOURCES.md").read_text(encoding="utf-8")
    rows = {line.split("`")[1]: line for line in table.splitlines() if line.startswith("| `")}
    assert set(rows) == {p.name for p in folder.glob("*.png")} \
        == {f"{name}.png" for name in PHOTOGRAPH_NAMES}
    for name, row in rows.items():
        licence = row.rstrip(" |").rsplit("|", 1)[1].lower()
        assert "cc0" in licence or "public domain" in licence \
            or "no known copyright restrictions" in licence, name
    with pytest.raises(KeyError, match="moon"):
        photograph_path("moon")  # installed with scikit-image, no licence stated: not shipped


def test_photo_layout_has_a_subject_at_the_focus_and_a_background_behind():
    config = SceneConfig(width=160, height=120, frames=3, layout="photo")
    focused = 0
    for seed in range(8):
        frames, focus = render_scene(seed, config)
        again, focus_again = render_scene(seed, config)
        assert focus == focus_again and np.array_equal(frames[0][1], again[0][1])
        depth = frames[0][1]
        assert np.isfinite(depth).all() and depth.min() > 0
        # much of the frame lies behind the subject (background, ground, objects) ...
        assert np.mean(depth > focus * 1.5) > 0.2
        # ... and the focus distance is the subject's depth, except for an occasional miss
        focused += np.mean(np.abs(depth / focus - 1) < 0.1) > 0.05
    assert focused >= 6


def test_photo_scene_folder_records_the_focus_distance(tmp_path):
    config = SceneConfig(width=64, height=48, frames=2, layout="photo")
    write_scene_folder(tmp_path, 2, config, seed=1, progress=False)
    recorded = json.loads((tmp_path / "seq_000" / "scene.json").read_text())
    assert recorded["focus_distance"] > 0 and recorded["layout"] == "photo"


def test_scene_folder_does_not_depend_on_the_number_of_workers(tmp_path):
    config = SceneConfig(width=48, height=32, frames=2, leaves=4, layout="photo")
    write_scene_folder(tmp_path / "one", 3, config, seed=7, progress=False)
    write_scene_folder(tmp_path / "two", 3, config, seed=7, progress=False, workers=2)
    files = sorted(p.relative_to(tmp_path / "one") for p in (tmp_path / "one").rglob("*.*")
                   if p.name != LOCK_NAME)  # the lock names its holder's pid
    assert len(files) == 1 + 3 * 5  # description + per sequence: scene.json, 2 PNG, 2 NPY
    for name in files:
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes()


def test_bad_layout_is_refused():
    with pytest.raises(ParameterError, match="layout"):
        SceneConfig(layout="forest")


def test_defocus_profile_scales_with_the_frame_and_focuses():
    profile = DEFOCUS_PROFILES["dslr-840"]
    rng = np.random.default_rng(0)
    full = profile.lens(np.random.default_rng(5), 3.0, 840)
    half = profile.lens(np.random.default_rng(5), 3.0, 420)
    depths = np.array([3.0, 1e9, 1.5])
    r_full, r_half = coc_radius(depths, full), coc_radius(depths, half)
    assert r_full[0] == pytest.approx(0.0, abs=1e-9)
    low, high = profile.infinity_coc
    assert low <= r_full[1] <= high
    assert r_half[1] == pytest.approx(r_full[1] / 2, rel=1e-6)  # relative to the frame
    assert r_full[2] < 0  # in front of the focus
    assert abs(coc_radius(np.array([1e-3]), full)[0]) == pytest.approx(profile.max_coc_radius)
    draws = [coc_radius(np.array([1e9]), profile.lens(rng, 2.0, 840))[0] for _ in range(200)]
    assert low <= min(draws) and max(draws) <= high and np.std(draws) > 1
    with pytest.raises(ParameterError, match="infinity_coc"):
        DefocusProfile("bad", 840, (5.0, 1.0), 10.0)


def test_every_sequence_gets_its_own_profile_lens(tmp_path):
    # regression: the first sequence's camera (focus and blur scale) was reused for all others
    scenes = tmp_path / "scenes"
    write_scene_folder(scenes, 4, SceneConfig(width=64, height=48, frames=1, layout="photo"),
                       seed=5, progress=False)
    sequences = discover_sequences(scenes, "rgbd")
    config = SynthConfig(lens_sets=("dslr-840", "dslr-840-mild"), psf_bank="pixel4")
    jobs = plan_jobs(sequences, config)
    assert len(jobs) == 8
    for job in jobs:
        scene = json.loads((job.frame.rgb.parent.parent / "scene.json").read_text())
        camera = job.draw.lens
        assert camera.name == ("dslr-840" if job.sequence <= 4 else "dslr-840-mild")
        assert camera.focus_distance == pytest.approx(scene["focus_distance"])
    assert len({job.draw.lens.focus_distance for job in jobs}) == 4
    assert len({job.draw.lens.pixel_pitch for job in jobs}) == 8  # blur scale per sequence


def test_pixel4_bank_spans_the_fitted_shapes():
    alphas = {p.alpha for p in PIXEL4_PSF_BANK}
    kappas = {p.kappa for p in PIXEL4_PSF_BANK}
    assert min(alphas) <= 0.4 <= max(alphas) and 0.21 in kappas


def test_dataset_with_a_profile_uses_the_scene_focus(tmp_path):
    scenes = tmp_path / "scenes"
    write_scene_folder(scenes, 2, SceneConfig(width=96, height=64, frames=2, layout="photo"),
                       seed=2, progress=False)
    config = SynthConfig(lens_sets=("dslr-840",), psf_bank="pixel4", bit_depth=8,
                         noise_model="poisson-gaussian", noise_sigmas=(0.01,), max_layers=60)
    summary = synthesize_dataset(scenes, "rgbd", tmp_path / "dp", config, progress=False)
    assert summary["status"] == "complete"
    records = read_manifest(tmp_path / "dp" / "manifest.jsonl")
    focus = json.loads((scenes / "seq_000" / "scene.json").read_text())["focus_distance"]
    first = next(r for r in records.values() if r["key"].startswith("train/seq_001/"))
    assert first["camera"]["name"] == "dslr-840"
    assert first["camera"]["focus_distance"] == pytest.approx(focus)
    assert first["camera"]["max_coc_radius"] == pytest.approx(30.0 * 96 / 840)
    assert any(p.as_dict() == first["psf"] for p in PIXEL4_PSF_BANK)
    with pytest.raises(ParameterError, match="psf_bank"):
        SynthConfig(psf_bank="canon")
    with pytest.raises(ParameterError, match="dslr-840"):
        SynthConfig(lens_sets=("dslr",))


def test_a_camera_can_keep_its_ratios_and_light_with_the_banks_shapes(tmp_path):
    from dualpixel.calibration.camera import DPCamera
    from dualpixel.optics import BROAD_PSF_BANK, PSFParams

    scenes = tmp_path / "scenes"
    write_scene_folder(scenes, 12, SceneConfig(width=64, height=48, frames=1, layout="photo"),
                       seed=6, progress=False)
    sequences = discover_sequences(scenes, "rgbd")
    fitted = PSFParams(n=3, alpha=0.45, beta=0.2, kappa=0.21)
    camera = DPCamera(name="c", width=840, disparity_ratio=(0.7, 0.96, 1.0), psf=fitted,
                      light="linear").to_dict()
    own = plan_jobs(sequences, SynthConfig(lens_sets=("dslr-840",), camera=camera,
                                           psf_bank="broad"))
    assert {job.draw.psf for job in own} == {fitted}  # default: the camera's fitted shape
    config = SynthConfig(lens_sets=("dslr-840",), camera=camera, psf_bank="broad",
                         psf_shapes="bank")
    drawn = plan_jobs(sequences, config)
    shapes = {job.draw.psf for job in drawn}
    assert len(shapes) >= 6 and shapes <= set(BROAD_PSF_BANK)
    assert all(job.draw.disparity_ratio == (0.7, 0.96, 1.0) for job in drawn)
    assert all(job.draw.light == "linear" for job in drawn)
    assert config.as_dict()["psf_shapes"] == "bank"
    assert "psf_shapes" not in SynthConfig(camera=camera).as_dict()  # old datasets unchanged
    with pytest.raises(ParameterError, match="needs a camera"):
        SynthConfig(psf_shapes="bank")
    with pytest.raises(ParameterError, match="psf_shapes must be one of camera, bank"):
        SynthConfig(camera=camera, psf_shapes="wide")
    kappas = {p.kappa for p in BROAD_PSF_BANK}
    betas = {p.beta for p in BROAD_PSF_BANK}
    assert min(kappas) < 0.1 and max(kappas) > 0.4 and max(betas) >= 0.9


def test_relief_varies_depth_inside_surfaces_within_its_bound(tmp_path):
    flat_config = SceneConfig(width=96, height=64, frames=1, layout="photo")
    relief_config = SceneConfig(width=96, height=64, frames=1, layout="photo", relief=0.1)
    (flat_rgb, flat_depth), = render_scene(3, flat_config)[0]
    (rgb_r, depth_r), = render_scene(3, relief_config)[0]
    assert np.array_equal(rgb_r, flat_rgb)  # the same scene, only its depth in relief
    ratio = depth_r / flat_depth
    assert 0.9 - 1e-4 <= ratio.min() and ratio.max() <= 1.1 + 1e-4
    assert np.mean(np.abs(ratio - 1) > 0.01) > 0.3  # most surfaces are not flat any more
    again, _ = render_scene(3, relief_config)
    assert np.array_equal(again[0][1], depth_r)
    # a flat folder records its settings as before the option existed
    write_scene_folder(tmp_path / "flat", 1, flat_config, progress=False)
    assert "relief" not in json.loads((tmp_path / "flat" / "scenes.json").read_text())["config"]
    write_scene_folder(tmp_path / "relief", 1, relief_config, progress=False)
    with pytest.raises(InputFileError, match="relief"):
        write_scene_folder(tmp_path / "relief", 1, flat_config, progress=False)
