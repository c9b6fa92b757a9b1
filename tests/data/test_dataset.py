import numpy as np
import pytest
import torch

from dualpixel.data import (
    DPPatchDataset,
    PatchConfig,
    discover_dp_dataset,
    flip_horizontal,
    radial_distance,
)
from dualpixel.errors import InputFileError, ParameterError
from tests.conftest import write_dpdd_pairs


def test_radial_distance_is_one_at_corners_and_crops_consistently():
    full = radial_distance(30, 50)
    assert full[0, 0] == pytest.approx(1) and full[-1, -1] == pytest.approx(1)
    assert full.min() < 0.05 and full.max() <= 1 + 1e-6
    crop = radial_distance(10, 12, full_size=(30, 50), top=5, left=30)
    np.testing.assert_allclose(crop, full[5:15, 30:42], atol=1e-6)


def test_synthetic_sequences_are_found_and_cropped_at_one_place(tiny_synthetic_dataset):
    sequences = discover_dp_dataset(tiny_synthetic_dataset, "train")
    assert len(sequences) == 4 and all(len(s.frames) == 3 for s in sequences)
    data = DPPatchDataset(sequences, PatchConfig(patch_size=32, frames=3, flips=False))
    item = data[(0, 123)]
    assert item["left"].shape == (3, 3, 32, 32) and item["radial"].shape == (3, 1, 32, 32)
    # Same seed, same patch; the radial patch says where it came from.
    again = data[(0, 123)]
    for key in item:
        torch.testing.assert_close(item[key], again[key])
    full = radial_distance(64, 64)
    r = item["radial"][0, 0].numpy()
    matches = [(t, c) for t in range(33) for c in range(33)
               if np.allclose(full[t:t + 32, c:c + 32], r, atol=1e-6)]
    assert matches
    t, c = matches[0]
    from dualpixel.io.images import read_rgb
    frames = sequences[0].frames
    for k in range(3):  # every frame cropped at the same place
        target = read_rgb(frames[k].target)[t:t + 32, c:c + 32]
        np.testing.assert_allclose(item["target"][k].permute(1, 2, 0).numpy(), target)


def test_horizontal_flip_swaps_views():
    left = torch.arange(12.0).reshape(1, 1, 3, 4).expand(1, 3, 3, 4)
    right = -left
    item = {"left": left, "right": right, "target": left * 0, "radial": left[:, :1]}
    flipped = flip_horizontal(item)
    torch.testing.assert_close(flipped["left"], right.flip(-1))
    torch.testing.assert_close(flipped["right"], left.flip(-1))
    torch.testing.assert_close(flipped["radial"], item["radial"].flip(-1))


def test_flips_in_the_dataset_keep_left_right_geometry(tmp_path):
    write_dpdd_pairs(tmp_path, "train", ["a"], size=(16, 16))
    sequences = discover_dp_dataset(tmp_path, "train")
    plain = DPPatchDataset(sequences, PatchConfig(patch_size=None, flips=False))[(0, 0)]
    flipped = DPPatchDataset(sequences, PatchConfig(patch_size=None, flips=True))
    seen_swap = False
    for seed in range(20):
        item = flipped[(0, seed)]
        for h in (False, True):
            for v in (False, True):
                ref = flip_horizontal(plain) if h else plain
                ref = {k: x.flip(-2) for k, x in ref.items()} if v else ref
                if all(torch.equal(item[k], ref[k]) for k in item):
                    seen_swap |= h
                    break
            else:
                continue
            break
        else:
            pytest.fail("augmented item is not a DP-valid flip of the original")
    assert seen_swap


def test_real_pairs_and_flat_patch_rejection(tmp_path):
    write_dpdd_pairs(tmp_path, "train", ["x", "y"], size=(40, 48))
    target = tmp_path / "train_c/target/x.png"
    import cv2

    flat = np.full((40, 48, 3), 128, np.uint8)
    flat[:, 40:] = np.random.default_rng(0).integers(0, 255, (40, 8, 3))  # texture at the right
    cv2.imwrite(str(target), flat)
    sequences = discover_dp_dataset(tmp_path, "train")
    assert [s.name for s in sequences] == ["x", "y"]
    data = DPPatchDataset(sequences, PatchConfig(patch_size=8, min_sharpness=0.5, max_tries=50,
                                                 flips=False))
    for seed in range(5):
        radial = data[(0, seed)]["radial"][0, 0].numpy()
        full = radial_distance(40, 48)
        # the accepted patch lies (at least partly) in the textured columns
        lefts = [c for c in range(41) for t in range(33)
                 if np.allclose(full[t:t + 8, c:c + 8], radial, atol=1e-6)]
        assert max(lefts) > 32


def test_the_frame_cache_changes_no_patch(tmp_path):
    # the cache keeps 8-bit frames as uint8: the flat-patch test must read them in [0, 1] too
    write_dpdd_pairs(tmp_path, "train", ["x"], size=(40, 48))
    import cv2

    flat = np.full((40, 48, 3), 128, np.uint8)
    flat[:, 40:] = np.random.default_rng(0).integers(0, 255, (40, 8, 3))
    cv2.imwrite(str(tmp_path / "train_c/target/x.png"), flat)
    sequences = discover_dp_dataset(tmp_path, "train")
    config = PatchConfig(patch_size=8, min_sharpness=0.5, max_tries=50)
    plain, cached = DPPatchDataset(sequences, config), DPPatchDataset(sequences, config, cache=True)
    for seed in range(6):
        first, again = plain[(0, seed)], cached[(0, seed)]
        for key in first:
            torch.testing.assert_close(first[key], again[key], rtol=0, atol=0)


def test_bad_datasets_are_named(tmp_path):
    with pytest.raises(InputFileError, match=r"train_l/source: folder missing"):
        discover_dp_dataset(tmp_path, "train")
    write_dpdd_pairs(tmp_path, "train", ["a", "b"])
    (tmp_path / "train_r/source/b.png").unlink()
    with pytest.raises(InputFileError, match=r"right view of b\.png is missing"):
        discover_dp_dataset(tmp_path, "train")
    write_dpdd_pairs(tmp_path, "train", ["b"], seed=1)
    import cv2

    cv2.imwrite(str(tmp_path / "train_c/target/b.png"), np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(InputFileError, match=r"target/b\.png: size 10x10 differs"):
        discover_dp_dataset(tmp_path, "train")
    (tmp_path / "train_c/target/b.png").write_bytes(b"garbage")
    with pytest.raises(InputFileError, match=r"b\.png: cannot be read"):
        discover_dp_dataset(tmp_path, "train")
    empty = tmp_path / "empty"
    for folder in ("test_l/source", "test_r/source", "test_c/target"):
        (empty / folder).mkdir(parents=True)
    with pytest.raises(InputFileError, match="no images found"):
        discover_dp_dataset(empty, "test")
    small = tmp_path / "small"
    write_dpdd_pairs(small, "train", ["c"], size=(40, 48))
    with pytest.raises(ParameterError, match=r"patch_size 64 exceeds .*c.* \(48x40\)"):
        DPPatchDataset(discover_dp_dataset(small, "train"), PatchConfig(patch_size=64))
    # issue #73: the setting is named, not only the data it does not fit
    with pytest.raises(ParameterError, match=r"sequence_frames is 4 but no sequence has that "
                                             r"many frames .*lower sequence_frames"):
        DPPatchDataset(discover_dp_dataset(small, "train"), PatchConfig(patch_size=32, frames=4))
