"""Seconds per training item (one random crop of views + target, flat-patch test, flips), in one
run, for the three ways frames reach a patch: decoded from PNG each time, the in-memory cache
(per process), and the frame store (decoded once into memory-mapped files, shared by processes).

The default data are the 7 real Canon scenes in ../shared (840x512, read in place); ``--dataset``
takes any DPDD-layout dataset, e.g. ``runs/data/mix-synth-train`` (840x560). One thread, as in a
loader process.

    .venv/bin/python benchmarks/bench_loading.py [--patch 512] [--items 60] [--dataset DIR]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import torch

from dualpixel.data import DPPatchDataset, PatchConfig
from dualpixel.data.layout import discover_dp_dataset, discover_scene_folders
from dualpixel.io.dpdd import role_folder

CANON = Path(__file__).resolve().parents[2] / "shared" / "data" / "canon-dp-real"


def seconds_per_item(dataset: DPPatchDataset, count: int, items: int) -> float:
    """Mean seconds per item over ``items`` calls, after one warm-up pass over every frame."""
    for index in range(count):
        dataset[(index, 0)]
    started = time.perf_counter()
    for step in range(items):
        dataset[(step % count, step + 1)]
    return (time.perf_counter() - started) / items


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", type=Path, default=CANON)
    parser.add_argument("--split", default="train")
    parser.add_argument("--patch", type=int, default=512)
    parser.add_argument("--items", type=int, default=60)
    parser.add_argument("--frames", type=int, default=20, help="use the first N frames")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if role_folder(args.dataset, args.split, "left").is_dir():
        sequences = discover_dp_dataset(args.dataset, args.split)
    else:
        sequences, _ = discover_scene_folders(args.dataset)
    sequences = sequences[: args.frames]
    config = PatchConfig(patch_size=args.patch, min_sharpness=0.01)
    print(f"{len(sequences)} frames of {sequences[0].width}x{sequences[0].height} from "
          f"{args.dataset}, {args.patch}-px crops, 1 thread")
    with tempfile.TemporaryDirectory() as store:
        cases = {
            "PNG each time": DPPatchDataset(sequences, config),
            "memory cache": DPPatchDataset(sequences, config, cache=True),
            "frame store": DPPatchDataset(sequences, config, store=store),
        }
        results = {name: seconds_per_item(data, len(sequences), args.items)
                   for name, data in cases.items()}
    base = results["PNG each time"]
    for name, seconds in results.items():
        print(f"{name:>14}: {1000 * seconds:6.1f} ms per item  ({base / seconds:4.1f}x PNG)")


if __name__ == "__main__":
    main()
