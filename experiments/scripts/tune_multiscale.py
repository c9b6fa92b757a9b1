"""Choose the multiscale fusion's sigma on the tuning set (scripts/make_tune_data.sh).

Runs the network once per frame at full and at half resolution, then fuses the two with each
candidate sigma (dualpixel.inference.multiscale.fuse_scales) and prints the mean PSNR of each,
beside the full-resolution pass alone. Usage:

    .venv/bin/python scripts/tune_multiscale.py [--data DIR] [--checkpoint rdpd-light]
"""

from __future__ import annotations

import argparse

import numpy as np
from tqdm import tqdm

from dualpixel.api import load_model
from dualpixel.data.layout import discover_dp_dataset, read_frame
from dualpixel.evaluation.metrics import psnr
from dualpixel.inference import Deblurrer
from dualpixel.inference.multiscale import fuse_scales, half_resolution, upsample


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="runs/data/tune-synth")
    parser.add_argument("--split", default="test")
    parser.add_argument("--checkpoint", default="rdpd-light")
    parser.add_argument("--sigmas", default="1,2,3,4,6", help="candidates, px at full resolution")
    args = parser.parse_args()
    sigmas = [float(s) for s in args.sigmas.split(",")]
    model = load_model(args.checkpoint)
    fine_pass, coarse_pass = Deblurrer(model), Deblurrer(model)
    scores: dict[str, list[float]] = {"full resolution only": [], "half resolution only": []}
    sequences = discover_dp_dataset(args.data, args.split)
    frames = sum(len(sequence.frames) for sequence in sequences)
    bar = tqdm(total=frames, desc="frames")
    for sequence in sequences:
        fine_pass.reset()  # a recurrent model starts each sequence afresh
        coarse_pass.reset()
        for paths in sequence.frames:
            frame = read_frame(paths)
            fine = fine_pass(frame["left"], frame["right"])
            coarse = coarse_pass(half_resolution(frame["left"]), half_resolution(frame["right"]))
            target = frame["target"]
            scores["full resolution only"].append(psnr(fine, target))
            upsampled = upsample(coarse, *target.shape[:2])
            scores["half resolution only"].append(psnr(np.clip(upsampled, 0, 1), target))
            for sigma in sigmas:
                scores.setdefault(f"fused, sigma {sigma:g} px", []).append(
                    psnr(fuse_scales(fine, coarse, sigma), target))
            bar.update()
    bar.close()
    print(f"{frames} frames of {args.data} ({args.split}), {args.checkpoint}")
    for name, values in scores.items():
        print(f"  {name:24s} {np.mean(values):.3f} dB")


if __name__ == "__main__":
    main()
