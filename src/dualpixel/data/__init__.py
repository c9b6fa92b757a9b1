"""Datasets for training and evaluation: the DPDD layout, patches, the radial distance channel."""

from dualpixel.data.dataset import DPPatchDataset, PatchConfig, flip_horizontal, sharpness
from dualpixel.data.layout import DPFramePaths, DPSequence, discover_dp_dataset
from dualpixel.data.radial import radial_distance

__all__ = [
    "DPFramePaths",
    "DPPatchDataset",
    "DPSequence",
    "PatchConfig",
    "discover_dp_dataset",
    "flip_horizontal",
    "radial_distance",
    "sharpness",
]
