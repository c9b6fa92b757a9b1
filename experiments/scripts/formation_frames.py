"""Frames of our full formation laid out as the dev scenes, so that the scripts reading the dev
scenes (``formation_radius_map.py`` and others) read them alike: the baseline a real view's
figure is compared with (issue #77, item 3).

Each frame of a synthetic DPDD-layout dataset (``dualpixel synth``, 8-bit) becomes
``OUT/scene_NN/`` with ``view0.png`` / ``view1.png`` (the left / right views, optionally
H.264-coded as one animation, as the 1620-px dev views were), ``target.png`` and, standing in
for the published DPDNet output the dev scenes carry, the target again as ``dpdnet.png``.

    dualpixel scenes -o runs/aperture/scenes --sequences 8 --frames 1 --size 840x560 \\
        --layout photographic --photos ../shared/data/photographs/validation --seed 51000
    dualpixel synth --input runs/aperture/scenes -o runs/aperture/synth-hd \\
        --camera canon-hd-linear --psf-bank pixel4 --noise-model poisson-gaussian \\
        --noise-sigmas 0.001 --bit-depth 8 --lens-sets dslr-840 --seed 41001
    python experiments/scripts/formation_frames.py runs/aperture/synth-hd \\
        runs/aperture/synth-scenes --h264 23
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from formation_radius_map import h264, write_dev_scene  # the dev views' coding and layout

from dualpixel.io.images import read_rgb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path, help="a synthetic dataset (DPDD layout)")
    parser.add_argument("out", type=Path)
    parser.add_argument("--h264", type=int, default=0, metavar="CRF",
                        help="code both views as one H.264 animation at CRF (needs PyAV)")
    args = parser.parse_args()
    combined = sorted(args.dataset.glob("*_c/source/*/*.png"))
    if not combined:
        raise SystemExit(f"{args.dataset}: no frames (*_c/source/SEQ/FRAME.png)")
    for number, path in enumerate(combined):
        views = np.stack([read_rgb(Path(str(path).replace("_c/source", f"_{side}/source")))
                          for side in "lr"])
        if args.h264:
            views = h264(views, args.h264)
        target = read_rgb(Path(str(path).replace("_c/source", "_c/target")))
        write_dev_scene(args.out / f"scene_{number:02d}", views, target)
    print(f"{len(combined)} frames -> {args.out}")


if __name__ == "__main__":
    main()
