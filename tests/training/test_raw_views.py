"""raw_views: model: raw-stored synthetic frames are trained and validated on as `deblur
--encoding linear` feeds raw views to the model; display-stored ones are untouched."""

import pickle

import numpy as np
import pytest
import torch

from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset
from dualpixel.errors import ParameterError
from dualpixel.inference.encoding import ViewEncoding, deblur_encoded, to_model
from dualpixel.io.images import read_view
from dualpixel.training import load_config, train
from dualpixel.training.raw_views import raw_views_transform, stored_black_level

BLACK = 0.0625


@pytest.fixture(scope="module")
def raw_dataset(tmp_path_factory):
    """Two scenes of two 64x64 frames stored as 16-bit raw values above a black level."""
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
    from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder

    scenes = tmp_path_factory.mktemp("raw_scenes")
    write_scene_folder(scenes, 2, SceneConfig(width=64, height=64, frames=2, leaves=8), seed=5,
                       progress=False)
    root = tmp_path_factory.mktemp("raw_dp")
    config = SynthConfig(lens_sets=("set1",), max_layers=40, noise_sigmas=(0.01,), seed=5,
                         light="linear", encoding="linear", black_level=BLACK,
                         raw_gains=(0.4, 0.8), bit_depth=16)
    synthesize_dataset(scenes, "rgbd", root, config, workers=1, progress=False)
    return root


def _recording(seen):
    """A stand-in network that keeps the views it is handed in ``seen``."""
    def network(left, right):
        seen["left"], seen["right"] = left, right
        return left
    return network


def test_black_level_is_read_from_the_dataset(raw_dataset, tiny_synthetic_dataset, tmp_path):
    assert stored_black_level(raw_dataset) == BLACK
    assert stored_black_level(tiny_synthetic_dataset) is None  # display values
    assert stored_black_level(tmp_path) is None  # not made by synth
    assert raw_views_transform([str(raw_dataset)], "stored") is None
    assert raw_views_transform(str(tiny_synthetic_dataset), "model") is None
    transform = raw_views_transform([str(raw_dataset), str(tiny_synthetic_dataset)], "model")
    assert transform.roots == ((raw_dataset.resolve(), BLACK),)
    assert pickle.loads(pickle.dumps(transform)) == transform  # loader processes get a copy


def test_crops_are_what_deblur_feeds_the_model_for_raw_views(raw_dataset,
                                                             tiny_synthetic_dataset):
    """Whole frames through the dataset equal the views `deblur --encoding linear --black-level
    B --white-level 65535` hands the network for the same files, and the target is encoded
    alike; display-stored sequences pass unchanged."""
    roots = [str(raw_dataset), str(tiny_synthetic_dataset)]
    sequences = [s for root in roots for s in discover_dp_dataset(root, "train")]
    config = PatchConfig(patch_size=None, frames=1, flips=False)
    plain = DPPatchDataset(sequences, config)
    encoded = DPPatchDataset(sequences, config, transform=raw_views_transform(roots, "model"))
    raw_count = len(discover_dp_dataset(raw_dataset, "train"))
    for index, sequence in enumerate(sequences):
        mine, stored = encoded[(index, 1)], plain[(index, 1)]
        if index >= raw_count:
            for key in stored:
                assert torch.equal(mine[key], stored[key])
            continue
        frame, seen = sequence.frames[0], {}
        network = _recording(seen)
        views = [read_view(path)[0] for path in (frame.left, frame.right, frame.target)]
        linear = ViewEncoding("linear", BLACK * 65535, 65535)
        deblur_encoded(network, views[0], views[1], linear, scale=65535.0)
        for key in ("left", "right"):
            np.testing.assert_allclose(mine[key][0].permute(1, 2, 0).numpy(), seen[key],
                                       atol=1e-6)
        # the target at the views' exposure (the one the linear mode gives this frame)
        exposed = linear.exposed(views[0], views[1], scale=65535.0)
        assert exposed.light_gain > 1.0  # the raw frames are dark
        seen.clear()
        network(*to_model(views[2], views[2], exposed, scale=65535.0))
        np.testing.assert_allclose(mine["target"][0].permute(1, 2, 0).numpy(), seen["left"],
                                   atol=1e-6)
        # raw values are dark (exposure gain 0.4-0.8 above the black level): encoded, brighter
        assert float(mine["target"].mean()) > float(stored["target"].mean()) + 0.05


def test_training_and_validation_take_the_setting(raw_dataset, tmp_path):
    common = dict(model="rdpd", width=0.125, residual=True, synthetic_data=str(raw_dataset),
                  val_data=str(raw_dataset), val_split="train", patch_size=32,
                  sequence_batch=2, sequence_frames=1, epochs=1, iterations_per_epoch=2,
                  workers=0, learning_rate=1e-9, tensorboard=False)
    scores = {}
    for setting in ("stored", "model"):
        result = train(load_config(None, dict(common, raw_views=setting)),
                       tmp_path / setting, progress=False)
        scores[setting] = result.history[-1]["val_psnr"]
    # the same (untrained) weights scored on other values: raw-stored frames are read differently
    assert abs(scores["model"] - scores["stored"]) > 0.5
    with pytest.raises(ParameterError, match="raw_views must be one of stored, model"):
        load_config(None, dict(common, raw_views="linear"))
