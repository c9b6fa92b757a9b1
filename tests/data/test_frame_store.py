"""Decoded frames on disk, shared by loader processes through memory maps."""

import cv2
import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset
from dualpixel.data import frame_store as frame_store_module
from dualpixel.errors import InputFileError
from tests.conftest import write_dpdd_pairs


def items(dataset, keys):
    return [dataset[key] for key in keys]


def assert_same(first, second):
    for a, b in zip(first, second):
        assert a.keys() == b.keys()
        for key in a:
            torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)


def test_the_store_gives_the_same_patches_and_decodes_each_frame_once(tmp_path, monkeypatch):
    write_dpdd_pairs(tmp_path / "ds", "train", ["a", "b", "c"], size=(40, 48))
    sequences = discover_dp_dataset(tmp_path / "ds", "train")
    config = PatchConfig(patch_size=16, min_sharpness=0.05)
    keys = [(i % 3, seed) for i, seed in enumerate(range(9))]
    plain = items(DPPatchDataset(sequences, config), keys)
    assert_same(plain, items(DPPatchDataset(sequences, config, store=tmp_path / "s"), keys))
    entries = sorted((tmp_path / "s").glob("*.npy"))
    assert len(entries) == 3 and not list((tmp_path / "s").glob(".*"))  # no partial files
    stored = np.load(entries[0])
    assert stored.dtype == np.uint8 and stored.shape == (3, 40, 48, 3)  # left, right, target

    def no_decoding(frame):
        raise AssertionError(f"decoded {frame.left} again")

    monkeypatch.setattr(frame_store_module, "read_frame", no_decoding)
    assert_same(plain, items(DPPatchDataset(sequences, config, store=tmp_path / "s"), keys))


def test_an_edited_source_is_decoded_again(tmp_path):
    write_dpdd_pairs(tmp_path / "ds", "train", ["a"], size=(24, 24))
    sequences = discover_dp_dataset(tmp_path / "ds", "train")
    config = PatchConfig(patch_size=None, flips=False)
    DPPatchDataset(sequences, config, store=tmp_path / "s")[(0, 0)]
    cv2.imwrite(str(tmp_path / "ds/train_c/target/a.png"), np.full((24, 24, 3), 7, np.uint8))
    item = DPPatchDataset(sequences, config, store=tmp_path / "s")[(0, 0)]
    assert torch.allclose(item["target"], torch.tensor(7 / 255))
    assert len(list((tmp_path / "s").glob("*.npy"))) == 2


def test_loader_processes_share_the_store(tmp_path):
    write_dpdd_pairs(tmp_path / "ds", "train", ["a", "b"], size=(32, 40))
    sequences = discover_dp_dataset(tmp_path / "ds", "train")
    dataset = DPPatchDataset(sequences, PatchConfig(patch_size=16), store=tmp_path / "s")
    batches = [[(0, 1), (1, 2)], [(1, 3), (0, 4)], [(0, 5), (1, 6)]]
    alone = list(DataLoader(dataset, batch_sampler=batches, num_workers=0))
    shared = list(DataLoader(dataset, batch_sampler=batches, num_workers=2))
    assert_same(alone, shared)


def test_a_broken_entry_is_named(tmp_path):
    write_dpdd_pairs(tmp_path / "ds", "train", ["a"], size=(24, 24))
    sequences = discover_dp_dataset(tmp_path / "ds", "train")
    store = frame_store_module.FrameStore(tmp_path / "s")
    entry = store.entry(sequences[0].frames[0])
    entry.parent.mkdir()
    entry.write_bytes(b"not a numpy file")
    with pytest.raises(InputFileError, match="delete it"):
        DPPatchDataset(sequences, PatchConfig(patch_size=8), store=tmp_path / "s")[(0, 0)]


def test_no_file_stays_open_per_frame(tmp_path):
    import os

    write_dpdd_pairs(tmp_path / "ds", "train", [f"f{k}" for k in range(40)], size=(16, 16))
    sequences = discover_dp_dataset(tmp_path / "ds", "train")
    dataset = DPPatchDataset(sequences, PatchConfig(patch_size=8), store=tmp_path / "s")
    before = len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else None
    for index in range(len(sequences)):
        dataset[(index, index)]
    if before is not None:  # thousands of frames must not need thousands of descriptors
        assert len(os.listdir("/proc/self/fd")) < before + 5
