"""Fine-tune arms from rdpd-light.v16 that differ in how the training views are formed (issue
#77, item 3): as written (``plain``), lossily coded as the dev and unseen Canon views are (GIF
frames at 840 px, H.264 at 1620): each view on its own as a GIF or JPEG (``coded``) or the two
views together as an H.264 animation, as the 1620-px views were made (``h264``); or with the
Canon cameras' disparity ratio falling towards the frame's sides as measured on the dev pairs
(``falloff``: ``calibrate camera --falloff`` gives 0.35 at 840 px and 0.58 at 1620;
``docs/formation.md``).

The arms train alike on the photographic recipe's seven on-the-fly cameras (the same crops and
draws, from the v17 run's data folder): 2 epochs of 300 iterations, learning rate 1e-4 cosine.
In the ``coded`` arm each display-encoded training crop is, with probability 1/2, stored as a
GIF frame (its own palette of 32-256 colours, Floyd-Steinberg dither) or a JPEG of quality
50-95, each view on its own; in the ``h264`` arm, with probability 1/2, the pair is coded as an
H.264 animation (libx264 through PyAV, ``pip install av``; each view held 4 frames, twice round,
CRF 18-30; each view back as the mean of its second round: ``formation_radius_map.h264``).
Targets stay clean, raw (linear) views are never coded.

    python experiments/scripts/coded_training.py ARM OUT [--data runs/rdpd-light-photographs]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from coded_views import code  # this folder's GIF and JPEG round trips
from formation_radius_map import h264  # this folder's H.264 animation round trip

from dualpixel.data.dataset import DPPatchDataset
from dualpixel.training import load_config, train


def coded(view: torch.Tensor, rng: np.random.Generator, codec: str) -> torch.Tensor:
    """A ``(T, 3, H, W)`` view in [0, 1] coded frame by frame (grey views as one channel)."""
    frames = []
    grey = bool(torch.equal(view[:, 0], view[:, 1]) and torch.equal(view[:, 1], view[:, 2]))
    colours, quality = int(rng.integers(32, 257)), int(rng.integers(50, 96))
    for frame in view:
        image = (frame.permute(1, 2, 0).numpy() * 255 + 0.5).clip(0, 255).astype(np.uint8)
        image = np.ascontiguousarray(image[..., 1] if grey else image[..., ::-1])  # grey, BGR
        out = code(image, "gif" if codec == "gif" else f"jpeg{quality}", colours)
        out = np.repeat(out[..., None], 3, axis=2) if grey else out[..., ::-1]
        frames.append(torch.from_numpy(out.astype(np.float32) / 255).permute(2, 0, 1))
    return torch.stack(frames)


def code_half_the_display_items(salt: int, code_item) -> None:
    """Make ``code_item(item, rng)`` change every display-encoded training item with
    probability 1/2, drawn from its key and ``salt`` (raw views and whole frames untouched)."""
    plain = DPPatchDataset.__getitem__

    def getitem(self, key):
        item = plain(self, key)
        if getattr(self, "raw_black_level", None) is not None or not isinstance(key, tuple):
            return item
        rng = np.random.default_rng((int(key[0]), int(key[1]) % 2**62, salt))
        if rng.uniform() < 0.5:
            code_item(item, rng)
        return item

    DPPatchDataset.__getitem__ = getitem


def code_training_views() -> None:
    """Each view of half the display-encoded crops a GIF frame or a JPEG, on its own."""

    def code_item(item, rng):
        codec = "gif" if rng.uniform() < 0.5 else "jpeg"
        for name in ("left", "right"):
            item[name] = coded(item[name], rng, codec)

    code_half_the_display_items(77, code_item)


def code_training_pairs() -> None:
    """Half the display-encoded pairs an H.264 animation of both views."""

    def code_item(item, rng):
        crf = int(rng.integers(18, 31))
        for t in range(item["left"].shape[0]):
            pair = torch.stack((item["left"][t], item["right"][t])).permute(0, 2, 3, 1)
            coded_pair = torch.from_numpy(h264(pair.numpy(), crf, hold=4, loops=2))
            item["left"][t], item["right"][t] = coded_pair.permute(0, 3, 1, 2)

    code_half_the_display_items(264, code_item)


#: ``dualpixel calibrate camera --falloff`` on the dev Canon pairs (840 px; 1620 px with
#: ``--max-radius 24 --skip-misaligned``).
FALLOFF = {"canon-840-linear": 0.354, "canon-840": 0.354, "canon-hd-linear": 0.585}


def fall_off_towards_the_sides() -> None:
    """Give the Canon cameras of every training set their measured disparity falloff."""
    import dataclasses

    from dualpixel.synthesis.dataset import SynthConfig

    plain = SynthConfig.dp_camera

    def dp_camera(self):
        camera = plain(self)
        if camera is not None and camera.name in FALLOFF:
            camera = dataclasses.replace(camera, disparity_falloff=FALLOFF[camera.name])
        return camera

    SynthConfig.dp_camera = dp_camera


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("arm", choices=("plain", "coded", "h264", "falloff"))
    parser.add_argument("output", type=Path)
    parser.add_argument("--data", type=Path, default=Path("runs/rdpd-light-photographs"))
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    family = args.data / "phases" / "family" / "config.yaml"
    config = load_config(family, {
        "epochs": 2, "iterations_per_epoch": 300, "learning_rate": 1e-4, "lr_schedule": "cosine",
        "val_data": str(args.data / "data" / "canon-840-test"), "val_limit": 4,
        "threads": args.threads, "checkpoint_minutes": 10, "tensorboard": False})
    if args.arm == "coded":
        code_training_views()
    if args.arm == "h264":
        code_training_pairs()
    if args.arm == "falloff":
        fall_off_towards_the_sides()
    train(config, args.output, resume=(args.output / "config.yaml").exists(), progress=False)


if __name__ == "__main__":
    main()
