"""Temporal consistency of deblurred sequences (ours; issue #75): flicker in static regions.

Between consecutive frames of a sequence, the pixels where the sharp target hardly changes
(its grey level, after a Gaussian of 1 px, moves by less than :data:`STATIC_LEVELS` of 255) show
nothing that moved; there a method's frame-to-frame change is flicker, up to the target's own
change (its noise). Per method the mean absolute change over those pixels, in levels of 255,
beside the target's; ``excess`` is their difference: 0 is as steady as the scene, the input's
value shows what the blurred views themselves do.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

__all__ = ["STATIC_LEVELS", "FlickerMeter"]

#: A target pixel counts as static between two frames when its smoothed grey level moves by
#: less than this (levels of 255).
STATIC_LEVELS = 2.0


def _grey(image: np.ndarray) -> np.ndarray:
    grey = np.asarray(image, np.float32).mean(axis=2) * 255.0
    return cv2.GaussianBlur(grey, (0, 0), 1.0)


@dataclass
class FlickerMeter:
    """Pools the frame-to-frame change of every method over the static pixels of each pair of
    consecutive frames; :meth:`add` the frames of each sequence in order."""

    change: dict[str, float] = field(default_factory=dict)  # summed |delta| per method
    pixels: int = 0
    pairs: int = 0
    _last: tuple[str, np.ndarray, dict[str, np.ndarray]] | None = None

    def add(self, sequence: str, target: np.ndarray, images: dict[str, np.ndarray]) -> None:
        """One frame ``(H, W, 3)`` in [0, 1]: its target and each method's image (the input
        included), after the previous frame of the same ``sequence``."""
        grey_target = _grey(target)
        greys = {name: _grey(image) for name, image in images.items()}
        if self._last is not None and self._last[0] == sequence \
                and self._last[1].shape == grey_target.shape:
            _, last_target, last = self._last
            static = np.abs(grey_target - last_target) < STATIC_LEVELS
            count = int(static.sum())
            if count:
                self.pixels += count
                self.pairs += 1
                self.change["target"] = self.change.get("target", 0.0) + float(
                    np.abs(grey_target - last_target)[static].sum())
                for name, grey in greys.items():
                    if name in last:
                        self.change[name] = self.change.get(name, 0.0) + float(
                            np.abs(grey - last[name])[static].sum())
        self._last = (sequence, grey_target, greys)

    def table(self) -> dict[str, dict[str, float]]:
        """Per method: ``change`` and the target's ``target_change`` (mean |delta| over static
        pixels, levels of 255), ``excess`` (their difference) and the ``pairs`` pooled."""
        if not self.pixels:
            return {}
        target = self.change["target"] / self.pixels
        return {name: {"change": round(total / self.pixels, 4),
                       "target_change": round(target, 4),
                       "excess": round(total / self.pixels - target, 4), "pairs": self.pairs}
                for name, total in self.change.items() if name != "target"}

    def markdown(self) -> str:
        rows = ["| Method | change in static regions (levels) | target's | excess |",
                "|---|---|---|---|"]
        rows += [f"| {name} | {row['change']:.3f} | {row['target_change']:.3f} | "
                 f"{row['excess']:+.3f} |" for name, row in self.table().items()]
        return "\n".join(rows) + "\n"
