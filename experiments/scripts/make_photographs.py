"""Write the photographs that synthesis draws textures from into the package, once.

Reads each photograph of scikit-image's ``skimage.data`` whose docstring releases it into the
public domain or under CC0 (see ``src/dualpixel/synthesis/photographs/SOURCES.md``), reduces
the longer side to at most 640 pixels (area averaging), and writes an 8-bit PNG (grey or RGB as
the original). Synthesis then depends on these files alone, not on the installed packages.

    python experiments/scripts/make_photographs.py        # needs scikit-image 0.26
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import skimage
import skimage.data

from dualpixel.synthesis.textures import PHOTOGRAPH_NAMES

LONG_SIDE = 640
FOLDER = Path(__file__).resolve().parents[2] / "src" / "dualpixel" / "synthesis" / "photographs"


def main() -> None:
    print(f"scikit-image {skimage.__version__}")
    for name in PHOTOGRAPH_NAMES:
        image = np.asarray(getattr(skimage.data, name)())
        if image.ndim == 3:
            image = image[:, :, :3]
        scale = min(1.0, LONG_SIDE / max(image.shape[:2]))
        if scale < 1.0:
            image = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        if image.ndim == 3:
            image = image[:, :, ::-1]  # OpenCV writes BGR
        path = FOLDER / f"{name}.png"
        if not cv2.imwrite(str(path), np.ascontiguousarray(image),
                           [cv2.IMWRITE_PNG_COMPRESSION, 9]):
            raise SystemExit(f"{path}: could not be written")
        print(f"{path.name}: {image.shape[1]}x{image.shape[0]}, {path.stat().st_size // 1024} KiB")


if __name__ == "__main__":
    main()
