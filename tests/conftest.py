"""Shared fixtures. Data from ../shared is read in place, never copied into the repo."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"shared data folder not found at {SHARED}")
    return SHARED


@pytest.fixture(scope="session")
def tiny_synthetic_dataset(tmp_path_factory) -> Path:
    """A small DP dataset made by the project's own pipeline: procedural scenes -> ``synth``.

    Two scenes of three 64x64 frames, two camera sets (4 sequences) in split ``train``.
    """
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
    from dualpixel.synthesis.scenes import SceneConfig, write_scene_folder

    scenes = tmp_path_factory.mktemp("tiny_scenes")
    write_scene_folder(scenes, 2, SceneConfig(width=64, height=64, frames=3, leaves=8), seed=3,
                       progress=False)
    root = tmp_path_factory.mktemp("tiny_dp")
    config = SynthConfig(cameras=("set1", "set3"), max_layers=40, noise_sigmas=(0.01,), seed=3)
    synthesize_dataset(scenes, "rgbd", root, config, workers=1, progress=False)
    return root


def write_dpdd_pairs(root: Path, split: str, names: list[str], size=(40, 48), seed=0) -> None:
    """Random real-style DP pairs (8-bit PNG) in the DPDD layout, for data-loading tests."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(seed)
    for name in names:
        for folder in (f"{split}_l/source", f"{split}_r/source", f"{split}_c/source",
                       f"{split}_c/target"):
            (root / folder).mkdir(parents=True, exist_ok=True)
            image = rng.integers(0, 256, size=(*size, 3), dtype=np.uint8)
            cv2.imwrite(str(root / folder / f"{name}.png"), image)
