"""How a ground truth off by a sub-pixel shift and a small scale (as the Pixel 4 captures of issue
#54 are: 0.2-2.4 px, 0.2-1.1 %) scores the blurred input, a perfect deblur (the sharp target
itself) and saved model outputs (`eval --save-outputs`), on a synthetic DP folder with targets
(docs/log/2026-11-28-eleventh-session.md).

    python experiments/scripts/misaligned_truth.py runs/rawpath/data/phone-test \
        v15=runs/rawpath/misalign/rdpd-light.v15/outputs
"""
import glob
import sys
from pathlib import Path

import cv2
import numpy as np

from dualpixel.evaluation.metrics import psnr

MISALIGNMENTS = ((0.0, 0.0), (0.5, 0.002), (1.0, 0.005), (2.0, 0.01))  # (px, scale)
BORDER = 16  # px left out at every edge (the warp's border)


def grey(path: str) -> np.ndarray:
    return cv2.imread(path, cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255


root, outputs = sys.argv[1], dict(arg.split("=", 1) for arg in sys.argv[2:])
scores: dict[tuple[float, str], list[float]] = {}
for path in sorted(glob.glob(f"{root}/test_c/target/seq_*/*.png")):
    name = Path(path).parent.name
    target = grey(path)
    images = {"input": grey(path.replace("/target/", "/source/")), "perfect deblur": target,
              **{label: grey(f"{folder}/{name}.png") for label, folder in outputs.items()}}
    h, w = target.shape
    for shift, scale in MISALIGNMENTS:
        m = np.float32([[1 + scale, 0, shift - scale * w / 2], [0, 1 + scale, -scale * h / 2]])
        truth = np.clip(cv2.warpAffine(target, m, (w, h), flags=cv2.INTER_CUBIC,
                                       borderMode=cv2.BORDER_REFLECT), 0, 1)
        crop = (slice(BORDER, -BORDER), slice(BORDER, -BORDER))
        for label, image in images.items():
            scores.setdefault((shift, label), []).append(psnr(image[crop], truth[crop]))
for shift, scale in MISALIGNMENTS:
    given = np.array(scores[(shift, "input")])
    cells = []
    for label in ["perfect deblur", *outputs]:
        gain = np.array(scores[(shift, label)]) - given
        cells.append(f"{label} {gain.mean():+.2f} dB ({int((gain < 0).sum())} lose)")
    print(f"truth off by {shift} px, {100 * scale:.1f} %: input {given.mean():.2f} dB; "
          + "; ".join(cells))
