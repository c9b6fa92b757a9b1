"""Shared fixtures. Data from ../shared is read in place, never copied into the repo."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
#: The suite's longest tests (one to several minutes each on 2 cores), started first so that the
#: short ones fill in around them instead of waiting for them at the end.
LONGEST = ("test_every_documented_command_runs", "test_tiny_model_overfits_a_tiny_batch",
           "test_onnx_matches_pytorch")


def pytest_configure(config: pytest.Config) -> None:
    """One compute thread per pytest-xdist worker: two workers of two threads each on two cores
    ran the longest test ten times slower than alone (164 s against 15 s)."""
    if hasattr(config, "workerinput"):
        import cv2
        import torch

        torch.set_num_threads(1)
        cv2.setNumThreads(1)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: index for index, name in enumerate(LONGEST)}  # the rest keep their order
    items.sort(key=lambda item: rank.get(getattr(item, "originalname", ""), len(LONGEST)))


def write_photographs(folder: Path) -> Path:
    """Three small photographs, each recognisable in a rendered frame by its colours: red only
    (green and blue 0), green only (red and blue 0), and grey (a grey file, R = G = B when
    read): patches of random levels with fine noise, so that they have regions and texture."""
    import cv2
    import numpy as np

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    for name, (height, width), channel in (("red", (120, 160), 2), ("green", (140, 150), 1),
                                           ("grey", (100, 200), None)):
        level = np.kron(rng.uniform(40, 250, (height // 20 + 1, width // 20 + 1)),
                        np.ones((20, 20)))[:height, :width]
        value = np.clip(level + rng.normal(0, 12, (height, width)), 1, 255).astype(np.uint8)
        if channel is None:
            cv2.imwrite(str(folder / f"{name}.png"), value)
        else:
            bgr = np.zeros((height, width, 3), np.uint8)
            bgr[:, :, channel] = value
            cv2.imwrite(str(folder / f"{name}.png"), bgr)
    return folder


@pytest.fixture(scope="session")
def photo_folder(tmp_path_factory) -> Path:
    """:func:`write_photographs` in a folder of the session's."""
    return write_photographs(tmp_path_factory.mktemp("photographs"))


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
    config = SynthConfig(lens_sets=("set1", "set3"), max_layers=40, noise_sigmas=(0.01,), seed=3)
    synthesize_dataset(scenes, "rgbd", root, config, workers=1, progress=False)
    return root


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory) -> Path:
    """An untrained light RDPD (width 0.125, residual) as a .safetensors file, for commands."""
    import torch

    from dualpixel.models import build_model, save_model

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("ckpt") / "tiny.safetensors"
    save_model(path, build_model("rdpd", width=0.125, residual=True))
    return path


@pytest.fixture(scope="session")
def behind_focus_frame() -> dict:
    """A synthetic DP frame (192x320, no noise or distortion) focused on a near plane (the left
    40 %) with a textured background 3 m away, behind the focus plane (about 2.5 px blur)."""
    import cv2
    import numpy as np

    import dualpixel

    rng = np.random.default_rng(4)
    noise = cv2.GaussianBlur(rng.standard_normal((192, 320, 3)).astype(np.float32), (0, 0), 2.0)
    rgb = np.clip(0.45 + 1.2 * noise, 0.02, 0.9)
    depth = np.where(np.arange(320)[None, :] < 128, 1.0, 3.0).repeat(192, 0).astype(np.float32)
    return dualpixel.synthesize(rgb, depth, lens_set="dslr-840", noise=False, distortion=False)


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


def busy_naf(model, *, std: float, seed: int):
    """``model`` (a NAF block or network) in eval mode with every block's scales and the head
    drawn at random (normal, ``std``): a fresh one is the identity, on which most checks of
    its output would pass whatever it computed."""
    import torch

    torch.manual_seed(seed)
    with torch.no_grad():
        for name, parameter in model.named_parameters():
            if name.endswith(("beta", "gamma")) or name.startswith("head."):
                parameter.normal_(0, std)
    return model.eval()


@pytest.fixture(scope="module")
def naf_model():
    """A tiny NAF-level network (model ``dpnaf``) whose blocks and head are not the identity,
    in eval mode."""
    from dualpixel.models import build_model

    return busy_naf(build_model("dpnaf", width=0.125, residual=True), std=0.1, seed=2)


@pytest.fixture(scope="module")
def refined_model():
    """A tiny recurrent network with a refiner whose correction is not zero (a fresh one adds
    nothing), in eval mode."""
    import torch

    from dualpixel.models import build_model

    torch.manual_seed(1)
    model = build_model("rdpd", width=0.125, residual=True, refiner=(8, 16, 16)).eval()
    torch.nn.init.normal_(model.refiner.head.weight, std=0.05)
    return model
