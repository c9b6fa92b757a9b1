"""On-the-fly training crops: rendered as written datasets are, drawn per sample, trained on."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.stats import ks_2samp
from torch.utils.data import DataLoader, default_collate

from dualpixel.data.dataset import PatchConfig, RenderedOn
from dualpixel.data.statistics import dataset_statistics
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.io.images import read_rgb
from dualpixel.models import load_model
from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
from dualpixel.synthesis.on_the_fly import (
    ON_THE_FLY_FILE,
    OnTheFlyDataset,
    SceneCache,
    write_on_the_fly,
    write_samples,
)
from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder
from dualpixel.training import load_config, train

SETTINGS = dict(lens_sets=("dslr-840",), psf_bank="pixel4", noise_model="poisson-gaussian",
                noise_sigmas=(0.006, 0.012, 0.025), bit_depth=8, distortion=True, seed=5)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    """16 one-frame photo scenes of 192x128 px."""
    root = tmp_path_factory.mktemp("otf") / "scenes"
    write_scene_folder(root, 16, SceneConfig(width=192, height=128, frames=1, layout="photo"),
                       seed=2, progress=False)
    return root


@pytest.fixture(scope="module")
def source(scenes) -> Path:
    folder = scenes.parent / "source"
    write_on_the_fly(folder, scenes, "rgbd", SynthConfig(**SETTINGS))
    return folder


def test_a_crop_is_the_region_of_the_frame_synth_writes_with_that_draw(scenes, source):
    written = scenes.parent / "written"
    synthesize_dataset(scenes, "rgbd", written, SynthConfig(**SETTINGS), workers=1,
                       progress=False)
    dataset = OnTheFlyDataset(source, PatchConfig(patch_size=None, flips=False))
    frame = dataset._frames_of_job(dataset.job(0, SETTINGS["seed"], 0))
    for role, folder in (("left", "train_l/source"), ("right", "train_r/source"),
                         ("target", "train_c/target")):
        on_disk = read_rgb(written / folder / "seq_001" / "frame_0000.png")
        np.testing.assert_array_equal(frame[role], on_disk)


def test_items_are_fixed_by_their_seed_and_differ_between_seeds(source):
    dataset = OnTheFlyDataset(source, PatchConfig(patch_size=64))
    assert len(dataset) == 16  # scenes x lens sets
    a, b = dataset[(3, 11)], dataset[(3, 11)]
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert set(a) == {"left", "right", "target", "radial"} and a["left"].shape == (1, 3, 64, 64)
    draws = {json.dumps(dataset.job(3, seed, 0).draw.describe(), sort_keys=True)
             for seed in range(6)}
    assert len(draws) == 6  # each sample its own camera, PSF shape, noise


def test_a_crop_rendered_alone_is_that_crop_of_the_whole_frame(source, monkeypatch):
    """Items render only their crop and its blur margin: the same crops, draws and flips as
    cut from whole rendered frames, the views within a level of rounding (the distortion's
    positions are mapped in another precision), the targets equal."""
    dataset = OnTheFlyDataset(source, PatchConfig(patch_size=64, min_sharpness=0.01))
    keys = [(3, 11), (0, 5), (9, 77), (15, 2)]
    alone = [dataset[key] for key in keys]
    monkeypatch.setattr(OnTheFlyDataset, "_pending",
                        lambda self, job: self._frames_of_job(job))  # whole frames, then cut
    for key, item in zip(keys, alone):
        whole = dataset[key]
        assert set(item) == set(whole)
        torch.testing.assert_close(item["target"], whole["target"], rtol=0, atol=0)
        for name in ("left", "right"):
            difference = (item[name] - whole[name]).abs()
            assert float(difference.max()) <= 1 / 255 + 1e-6, (key, name)
            assert float((difference > 0).float().mean()) < 0.01, (key, name)


def _per_frame(root: Path) -> dict[str, np.ndarray]:
    """Per frame (a frame's blocks share one draw, so frames are the independent samples):
    median block blur and |disparity| (the measures of ``dualpixel stats``), noise, brightness."""
    from dualpixel.data.layout import discover_any, read_frame
    from dualpixel.data.statistics import frame_statistics

    out: dict[str, list[float]] = {"blur": [], "disparity": [], "noise": [], "brightness": []}
    for sequence in discover_any(root, "train"):
        for paths in sequence.frames:
            images = read_frame(paths)
            stats = frame_statistics(images["left"], images["right"], images["target"], patch=32)
            out["blur"].append(float(np.median(stats.blur)) if stats.blur.size else 0.0)
            out["disparity"].append(float(np.median(np.abs(stats.disparity)))
                                    if stats.disparity.size else 0.0)
            out["noise"].append(stats.noise)
            out["brightness"].append(float(images["left"].mean()))
    return {k: np.asarray(v) for k, v in out.items()}


def test_samples_follow_the_written_datasets_distributions(scenes, source, tmp_path):
    """The same settings written (another seed) and drawn on the fly: the same blur, disparity,
    noise and brightness distributions (two-sample KS over frames, as ``dualpixel stats``
    measures them); a dataset of other settings is told apart by the same test."""
    written = tmp_path / "written"
    synthesize_dataset(scenes, "rgbd", written, SynthConfig(**{**SETTINGS, "seed": 77}),
                       workers=1, progress=False)
    samples = write_samples(OnTheFlyDataset(source, PatchConfig(patch_size=None)),
                            tmp_path / "samples", 32, seed=3)
    other = tmp_path / "other"
    synthesize_dataset(scenes, "rgbd", other, SynthConfig(**{
        **SETTINGS, "lens_sets": ("dslr-1680-crop",), "noise_sigmas": (0.05,), "seed": 77}),
        workers=1, progress=False)
    mine, theirs, others = _per_frame(samples), _per_frame(written), _per_frame(other)
    assert len(mine["noise"]) == 32 and len(theirs["noise"]) == 16
    for key in mine:
        assert ks_2samp(mine[key], theirs[key]).pvalue > 0.05, key
    for key in ("noise", "disparity", "blur"):
        assert ks_2samp(others[key], theirs[key]).pvalue < 0.01, key
    summary = dataset_statistics(samples, split="train", patch=32).summary()
    assert summary["frames"] == 32 and summary["noise_std"]["p50"] > 0


def _config(source: Path, validation: Path, **changes):
    data = source if isinstance(source, list) else str(source)
    values = dict(model="rdpd", width=0.125, residual=True, synthetic_data=data,
                  val_data=str(validation), val_split="train", val_limit=1, patch_size=32,
                  sequence_batch=2, sequence_frames=1, epochs=2, iterations_per_epoch=2,
                  workers=0, learning_rate=1e-3, lr_halve_every=1, tensorboard=False)
    values.update(changes)
    return load_config(None, values)


def test_training_on_the_fly_is_fixed_by_its_seed_and_resumes(source, scenes, tmp_path):
    validation = tmp_path / "val"
    synthesize_dataset(scenes, "rgbd", validation, SynthConfig(**SETTINGS), workers=1,
                       progress=False)
    straight = train(_config(source, validation), tmp_path / "straight", progress=False)
    train(_config(source, validation, workers=1), tmp_path / "again", progress=False)
    train(_config(source, validation, epochs=1), tmp_path / "resumed", progress=False)
    resumed = train(_config(source, validation), tmp_path / "resumed", resume=True,
                    progress=False)
    assert resumed.step == straight.step == 4
    a = load_model(tmp_path / "straight" / "last.safetensors").state_dict()
    for other in ("again", "resumed"):
        b = load_model(tmp_path / other / "last.safetensors").state_dict()
        for key in a:
            torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)
    # written and on-the-fly data together, in the order given
    mixed = train(_config([str(source), str(validation)], validation, epochs=1),
                  tmp_path / "mixed", progress=False)
    assert mixed.step == 2
    with pytest.raises(ParameterError, match="on-the-fly source; validate"):
        train(_config(source, source), tmp_path / "bad", progress=False)


def test_bad_sources_are_named_before_any_work(scenes, tmp_path):
    import shutil

    broken = shutil.copytree(scenes, tmp_path / "broken")
    depth = next(broken.rglob("*.npy"))
    values = np.load(depth)
    values[0, 0] = np.nan
    np.save(depth, values)
    with pytest.raises(InputFileError, match=r"\.npy.*NaN"):
        write_on_the_fly(tmp_path / "s1", broken, "rgbd", SynthConfig(**SETTINGS))
    values[0, 0] = -1.0
    np.save(depth, values)
    with pytest.raises(InputFileError, match=r"\.npy.*negative"):
        write_on_the_fly(tmp_path / "s1", broken, "rgbd", SynthConfig(**SETTINGS))
    no_depth = shutil.copytree(scenes, tmp_path / "nodepth")
    shutil.rmtree(next(no_depth.glob("seq_*")) / "depth")
    with pytest.raises(InputFileError, match="depth"):
        write_on_the_fly(tmp_path / "s2", no_depth, "rgbd", SynthConfig(**SETTINGS))
    with pytest.raises(ParameterError, match="nowhere"):
        SynthConfig(**{**SETTINGS, "lens_sets": ("nowhere",)})
    assert not (tmp_path / "s1" / ON_THE_FLY_FILE).exists()
    good = tmp_path / "good"
    write_on_the_fly(good, scenes, "rgbd", SynthConfig(**SETTINGS))
    with pytest.raises(ParameterError, match="patch_size 256 exceeds"):
        OnTheFlyDataset(good, PatchConfig(patch_size=256))


def test_synth_command_writes_a_source_and_names_bad_depth(scenes, tmp_path):
    import shutil

    from click.testing import CliRunner

    from dualpixel.cli.main import cli

    runner = CliRunner()
    result = runner.invoke(cli, ["synth", "--input", str(scenes), "-o", str(tmp_path / "fly"),
                                 "--source", "on-the-fly", "--lens-sets", "dslr-840"])
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "fly" / ON_THE_FLY_FILE).read_text())["config"][
        "lens_sets"] == ["dslr-840"]
    assert not list((tmp_path / "fly").rglob("*.png"))  # no frames written
    broken = shutil.copytree(scenes, tmp_path / "broken")
    depth = next(broken.rglob("*.npy"))
    np.save(depth, np.full_like(np.load(depth), -2.0))
    result = runner.invoke(cli, ["synth", "--input", str(broken), "-o", str(tmp_path / "f2"),
                                 "--source", "on-the-fly"])
    assert result.exit_code == 1 and depth.name in result.output
    assert "negative" in result.output and "Traceback" not in result.output


def test_rendering_on_the_device_gives_the_loaders_items(source, scenes, tmp_path):
    """render_items (the training process, all frames of a batch at once; here on CPU tensors)
    gives the items the loader makes one by one: the same draws, crops and flips; the frames
    equal to a level of rounding (the batched renderer is the default one to 100 dB). Loader
    processes that render their batches on the device train exactly as the training process
    rendering them does."""
    dataset = OnTheFlyDataset(source, PatchConfig(patch_size=64, min_sharpness=0.01))
    keys = [(3, 11), (0, 5), (9, 77), (3, 12)]
    together = dataset.render_items(keys, "cpu")
    for key, item in zip(keys, together):
        alone = dataset[key]
        assert set(item) == set(alone)
        for name in item:
            difference = (item[name] - alone[name]).abs()
            assert float(difference.max()) <= 1 / 255 + 1e-6, (key, name)
            assert float(difference.mean()) < 1e-4, (key, name)
    validation = tmp_path / "val"
    synthesize_dataset(scenes, "rgbd", validation, SynthConfig(**SETTINGS), workers=1,
                       progress=False)
    runs = [train(_config(source, validation, render_on="device", epochs=1),
                  tmp_path / f"device{k}", progress=False) for k in range(2)]
    assert runs[0].step == 2 and runs[0].history == [
        {**r, "seconds": s["seconds"]} for r, s in zip(runs[1].history, runs[0].history)]
    # a loader process rendering its batches as the training process does (one thread there:
    # the same to float rounding), spawned as training spawns them for a GPU
    loader = DataLoader(RenderedOn(dataset, "cpu"), batch_sampler=[keys], num_workers=1,
                        multiprocessing_context="spawn")
    batch, expected = next(iter(loader)), default_collate(together)
    for name in expected:
        assert float((batch[name] - expected[name]).abs().max()) < 1e-5, name
    workers = train(_config(source, validation, render_on="device", epochs=1, workers=1),
                    tmp_path / "device-workers", progress=False)
    assert workers.history[0]["loss"] == pytest.approx(runs[0].history[0]["loss"], rel=1e-5)
    with pytest.raises(ParameterError, match="render_on"):
        _config(source, validation, render_on="gpu")


def test_cached_scenes_give_the_same_items_without_reading_the_files_again(scenes, tmp_path):
    """Sources given a scene cache decode each scene once and share it: the items equal those
    read from the files each time, and a second pass renders with the scenes' RGB files gone."""
    copy = tmp_path / "scenes"
    shutil.copytree(scenes, copy)
    folder = tmp_path / "source"
    write_on_the_fly(folder, copy, "rgbd", SynthConfig(**SETTINGS))
    keys = [(3, 11), (0, 5), (9, 77)]
    read = OnTheFlyDataset(folder, PatchConfig(patch_size=64))
    expected = [read[key] for key in keys]
    scenes = SceneCache()
    cached = OnTheFlyDataset(folder, PatchConfig(patch_size=64), scenes=scenes)
    first = [cached[key] for key in keys]
    other = OnTheFlyDataset(folder, PatchConfig(patch_size=64), scenes=scenes)
    assert torch.equal(other[(3, 11)]["left"], first[0]["left"]) and len(scenes) == 3
    for sequence in ("seq_000", "seq_003", "seq_009"):
        for image in (copy / sequence / "rgb").iterdir():
            image.unlink()
    again = [cached[key] for key in keys]
    for want, *got in zip(expected, first, again):
        for item in got:
            assert all(torch.equal(want[k], item[k]) for k in want)
    with pytest.raises(InputFileError):
        read[(3, 11)]  # without the cache the files are read, and they are gone


def test_scenes_in_a_frame_store_are_decoded_once_for_every_process(scenes, tmp_path,
                                                                     monkeypatch):
    """With a frame store (training's ``frame_store``) each scene's RGB and depth are decoded
    once into the store: the items equal those read from the files, and another process's
    sources (a new cache on the same folder) render them without decoding a scene."""
    import dualpixel.synthesis.inputs as inputs
    from dualpixel.training.trainer import _synthetic_dataset

    keys = [(3, 11), (0, 5), (9, 77)]
    expected = [OnTheFlyDataset(source_of(scenes, tmp_path), PatchConfig(patch_size=64))[key]
                for key in keys]
    store = tmp_path / "store"
    config = _config(tmp_path / "source", tmp_path, frame_store=str(store), patch_size=64)
    got = [_synthetic_dataset(config, PatchConfig(patch_size=64), {})[key] for key in keys]
    assert len(list(store.glob("*.rgb.npy"))) == len(list(store.glob("*.depth.npy"))) == 3

    def no_decoding(*args, **kwargs):
        raise AssertionError("a scene was decoded again")

    monkeypatch.setattr(inputs, "load_frame", no_decoding)
    other = OnTheFlyDataset(tmp_path / "source", PatchConfig(patch_size=64),
                            scenes=SceneCache(store))
    again = [other[key] for key in keys]
    for want, *items in zip(expected, got, again):
        for item in items:
            assert all(torch.equal(want[k], item[k]) for k in want)


def source_of(scenes: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "source"
    write_on_the_fly(folder, scenes, "rgbd", SynthConfig(**SETTINGS))
    return folder
