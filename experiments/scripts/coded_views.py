"""A coded copy of a DPDD-layout dataset (issue #54; docs/log/2026-11-28-twelfth-session.md):
every view and target through GIF (256-colour adaptive palette, Floyd-Steinberg dither) or
JPEG, then stored as 8-bit PNG, as the dev views and the real pairs of GIF and video frames were.

    python experiments/scripts/coded_views.py SOURCE OUTPUT --codec gif|jpeg80
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import cv2
import numpy as np
from PIL import Image


def code(image: np.ndarray, codec: str, colours: int = 256) -> np.ndarray:
    """``image`` (8-bit, grey ``(H, W)`` or BGR ``(H, W, 3)``) through ``codec`` and back; a
    GIF's palette holds ``colours`` colours."""
    if codec == "gif":
        if image.ndim == 2:
            if colours >= 256:  # 256 grey levels: a GIF keeps every one
                return image
            paletted = Image.fromarray(image).quantize(colours,
                                                       dither=Image.Dither.FLOYDSTEINBERG)
            return np.asarray(paletted.convert("L")).copy()
        rgb = Image.fromarray(image[..., ::-1])
        paletted = rgb.quantize(colours, method=Image.Quantize.MEDIANCUT,
                                dither=Image.Dither.FLOYDSTEINBERG)
        return np.asarray(paletted.convert("RGB"))[..., ::-1].copy()
    quality = int(codec.removeprefix("jpeg"))
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.imdecode(data, cv2.IMREAD_UNCHANGED)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("--codec", required=True, choices=["gif", "jpeg80", "jpeg90"])
    args = parser.parse_args()
    if (args.output / ".done").is_file():
        return
    for path in sorted(args.source.rglob("*")):
        target = args.output / path.relative_to(args.source)
        if path.is_dir():
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix != ".png":
            shutil.copyfile(path, target)
            continue
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image.dtype != np.uint8:
            raise SystemExit(f"{path}: 8-bit images only, got {image.dtype}")
        cv2.imwrite(str(target), code(image, args.codec))
    (args.output / ".done").touch()


if __name__ == "__main__":
    main()
