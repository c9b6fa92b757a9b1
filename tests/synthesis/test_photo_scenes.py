"""Scenes whose surfaces are photographs: ``scenes --layout photographic --photos DIR``."""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.synthesis.photo_library import PhotoLibrary, shipped_library
from dualpixel.synthesis.scenes import (
    SceneConfig,
    photo_library,
    photo_regions,
    render_scene,
    write_scene_folder,
)

SMALL = SceneConfig(width=96, height=64, frames=2, layout="photographic")


def _from_photographs(rgb: np.ndarray) -> np.ndarray:
    """Pixels of a frame that come from :func:`tests.conftest.write_photographs`'s photographs
    (red only, green only, or grey); procedural textures and the package's photographs (tinted)
    are neither."""
    r, g, b = (rgb[..., k] for k in range(3))
    tol = 1.5 / 255
    red = (g < tol) & (b < tol) & (r > tol)
    green = (r < tol) & (b < tol) & (g > tol)
    grey = (abs(r - g) < tol) & (abs(g - b) < tol)
    return red | green | grey


def test_most_of_the_frame_is_photographs(photo_folder):
    library = photo_library(SMALL, photo_folder)
    assert len(library) == 3
    shares = []
    for seed in range(12):
        frames, focus = render_scene(seed, SMALL, library)
        assert len(frames) == 2 and focus is not None and focus > 0
        for rgb, depth in frames:
            assert rgb.shape == (64, 96, 3) and depth.shape == (64, 96)
            assert np.isfinite(depth).all() and depth.min() > 0
            shares.append(_from_photographs(rgb).mean())
    # a quarter of the objects are procedural; the background is always photographs
    assert np.mean(shares) > 0.7, np.mean(shares)
    assert min(shares) > 0.2


def test_a_frame_wider_than_every_photograph_is_tiled_without_enlarging(photo_folder):
    config = SceneConfig(width=320, height=200, frames=1, layout="photographic")
    library = photo_library(config, photo_folder)
    rgb, tiles = library.texture(np.random.default_rng(0), 216, 336)
    assert rgb.shape == (216, 336, 3) and tiles.max() >= 1
    assert _from_photographs(rgb).all()  # every tile is one of the photographs
    # never enlarged: each tile's texture has its photograph's fine noise (an enlarged crop
    # would be smoother than the original at the pixel scale)
    detail = np.abs(np.diff(rgb.max(axis=2), axis=1)).mean()
    original = np.abs(np.diff(library.image(0).max(axis=2), axis=1)).mean()
    assert detail > 0.6 * original
    frames, _ = render_scene(3, config, library)
    assert _from_photographs(frames[0][0]).mean() > 0.5


def test_depth_edges_follow_the_photographs_edges():
    """Regions split where the photograph's colour changes, not inside flat parts."""
    rgb = np.full((120, 160, 3), 0.2, np.float32)
    rgb[:, 80:] = (0.9, 0.6, 0.1)
    rgb[30:90, 20:60] = (0.1, 0.3, 0.9)
    rgb += np.random.default_rng(0).normal(0, 0.01, rgb.shape).astype(np.float32)
    labels = photo_regions(rgb)
    assert labels.shape == (120, 160)
    assert labels[60, 100] != labels[60, 10] != labels[60, 40]
    assert len(np.unique(labels[:, 82:])) == 1  # the flat right half is one region


def test_same_seed_same_frames_and_workers_do_not_matter(photo_folder, tmp_path):
    library = photo_library(SMALL, photo_folder)
    a = render_scene(5, SMALL, library)[0]
    b = render_scene(5, SMALL, library)[0]
    assert all(np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1]) for x, y in zip(a, b))
    digests = []
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        write_scene_folder(out, 3, SMALL, seed=2, progress=False, workers=workers,
                           photos=library)
        digests.append({p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
                        for p in sorted(out.rglob("*")) if p.is_file() and "lock" not in p.name})
    assert digests[0] == digests[1] and len(digests[0]) > 6


def test_the_folder_is_recorded_and_another_content_refused(photo_folder, tmp_path):
    import json
    import shutil

    photos = shutil.copytree(photo_folder, tmp_path / "photos")
    out = tmp_path / "scenes"
    write_scene_folder(out, 1, SMALL, progress=False, photos=photo_library(SMALL, photos))
    record = json.loads((out / "scenes.json").read_text())
    assert record["photos"]["photographs"] == 3 and record["config"]["layout"] == "photographic"
    assert json.loads((out / "seq_000" / "scene.json").read_text())["focus_distance"] > 0
    cv2.imwrite(str(photos / "red.png"), np.zeros((150, 150, 3), np.uint8))
    with pytest.raises(InputFileError, match=r"other settings.*digest"):
        write_scene_folder(out, 1, SMALL, progress=False, photos=photo_library(SMALL, photos))


def test_bad_photo_folders_are_named(tmp_path, photo_folder):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputFileError, match=r"empty: holds no photographs"):
        PhotoLibrary.from_folder(empty)
    (empty / "notes.txt").write_text("not a photograph")
    with pytest.raises(InputFileError, match=r"holds no photographs"):
        PhotoLibrary.from_folder(empty)
    with pytest.raises(InputFileError, match="photo folder not found"):
        PhotoLibrary.from_folder(tmp_path / "nowhere")
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "a.jpg").write_bytes(b"\xff\xd8 not really a jpeg \xff\xd9")
    with pytest.raises(InputFileError, match=r"a\.jpg: .*decoded"):
        PhotoLibrary.from_folder(broken)
    with pytest.raises(InputFileError, match="no readable photograph"), \
            warnings.catch_warnings(record=True):
        PhotoLibrary.from_folder(broken, skip_bad=True)
    tiny = tmp_path / "tiny"
    tiny.mkdir()
    cv2.imwrite(str(tiny / "t.png"), np.zeros((20, 30, 3), np.uint8))
    with pytest.raises(InputFileError, match=r"tiny: every photograph is smaller .*30x20"):
        photo_library(SceneConfig(width=320, height=240, layout="photographic"), tiny)
    with pytest.raises(ParameterError, match="photographic layout"):
        photo_library(SceneConfig(layout="photo"), photo_folder)


def test_an_unreadable_photograph_among_good_ones(tmp_path, photo_folder):
    import shutil

    mixed = shutil.copytree(photo_folder, tmp_path / "mixed")
    (mixed / "zz.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    with pytest.raises(InputFileError, match=r"zz\.png: .*--skip-bad"):
        photo_library(SMALL, mixed)
    with pytest.warns(UserWarning, match=r"left out 1 unreadable file\(s\): zz\.png"):
        library = photo_library(SMALL, mixed, skip_bad=True)
    assert len(library) == 3


def test_the_package_photographs_without_a_folder():
    library = photo_library(SMALL, None)
    assert library.folder == "(shipped)" and len(library) == len(shipped_library(32))
    frames, _ = render_scene(0, SMALL)  # the same library, implied
    assert np.array_equal(frames[0][0], render_scene(0, SMALL, library)[0][0][0])


def test_scenes_command_with_photos(tmp_path, photo_folder):
    runner = CliRunner()
    out = tmp_path / "out"
    result = runner.invoke(cli, ["-q", "scenes", "--output", str(out), "--photos",
                                 str(photo_folder), "--size", "96x64", "--frames", "1"])
    assert result.exit_code == 0, result.output
    assert "3 photographs" in result.output
    rgb = cv2.imread(str(out / "seq_000" / "rgb" / "frame_0000.png"))[:, :, ::-1] / 255.0
    assert _from_photographs(rgb).mean() > 0.2
    for args, code, message in (
        (["--photos", str(photo_folder), "--layout", "photo"], 2, "photographic"),
        (["--skip-bad"], 2, "--skip-bad"),
        (["--photos", str(tmp_path / "none")], 1, "photo folder not found"),
        (["--photos", str(photo_folder), "--output", str(photo_folder / "x")], 1, "input"),
    ):
        argv = ["scenes", "--output", str(tmp_path / "o2"), "--size", "96x64", *args]
        result = runner.invoke(cli, argv)
        assert result.exit_code == code and message in result.output, result.output
        assert "Traceback" not in result.output


def test_the_photographs_recipe_names_the_shared_splits():
    from dualpixel.training.recipe import load_recipe

    root = Path(__file__).resolve().parents[2]
    raw = (root / "recipes" / "rdpd-light-photographs.yaml").read_text()
    assert "photos: ../shared/data/photographs/train" in raw
    assert "photos: ../shared/data/photographs/validation" in raw
    if (root.parent / "shared" / "data" / "photographs").is_dir():
        import os

        here = os.getcwd()
        os.chdir(root)
        try:
            recipe = load_recipe(root / "recipes" / "rdpd-light-photographs.yaml")
        finally:
            os.chdir(here)
        steps = {s.name: s.args for s in recipe.data}
        assert steps["scenes-train"]["layout"] == "photographic"
        assert steps["scenes-test"]["photos"].endswith("validation")
