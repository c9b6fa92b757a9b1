"""Lossy coding of the stored DP views (ours): training views that passed through a coder.

Real DP views often reach a model through a lossy coder: the 1620-px DPDD views published as
video are frames of one H.264 animation of both views, where the second view is predicted from
the first; photographs are stored as JPEGs. A coder removes what the blur left of fine detail
and adds its own blocks, which a model trained on clean views sharpens into texture. With
:class:`ViewCoding` in a :class:`~dualpixel.synthesis.dataset.SynthConfig`, a share of the
stored 8-bit display-encoded frames have their two views coded (the combined image is then
their mean; the target stays clean; raw views are never coded):

* ``"h264"``: the pair as an H.264 animation (libx264, 4:2:0, through PyAV: ``pip install av``
  or ``dualpixel[video]``), each view held ``hold`` frames, ``loops`` times round, each view back
  as the mean of its frames after the first round; ``quality`` is the CRF range (lower: better).
* ``"jpeg"``: each view a JPEG on its own (OpenCV, 4:2:0); ``quality`` is the JPEG quality range.

Written datasets code whole frames; on-the-fly sources code what they render: each training crop
in loader processes (the coder's blocks then fall on the crop's grid), whole frames where they
are rendered on the training device.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np

from dualpixel.errors import ParameterError

__all__ = ["CODECS", "DEFAULT_QUALITY", "ViewCoding", "code_views", "h264_round_trip",
           "jpeg_round_trip"]

Codec = Literal["h264", "jpeg"]
#: The codecs and the range their quality takes.
CODECS: dict[str, tuple[int, int]] = {"h264": (0, 51), "jpeg": (1, 100)}
#: Each codec's quality range when none is given: the dev views' H.264 lies near CRF 23
#: (`docs/formation.md`), photographs' JPEGs at quality 50-95.
DEFAULT_QUALITY: dict[str, tuple[int, int]] = {"h264": (18, 30), "jpeg": (50, 95)}
#: What H.264 coding needs and where it is not installed.
_NEEDS_PYAV = "H.264 view coding needs PyAV: pip install av (or dualpixel[video])"


@dataclass(frozen=True)
class ViewCoding:
    """Which stored frames have their views coded, and how: ``share`` of them (drawn per frame
    from its seed) with ``codec`` at a quality drawn uniformly from ``quality`` (inclusive; None:
    :data:`DEFAULT_QUALITY`)."""

    codec: Codec = "h264"
    share: float = 0.5
    quality: tuple[int, int] | None = None
    hold: int = 4
    loops: int = 2

    def __post_init__(self) -> None:
        if self.codec not in CODECS:
            raise ParameterError(f"view_coding codec must be one of {', '.join(CODECS)}, got "
                                 f"{self.codec!r}")
        if isinstance(self.share, bool) or not isinstance(self.share, (int, float)) \
                or not 0.0 <= self.share <= 1.0:
            raise ParameterError(f"view_coding share must be a number in [0, 1], got "
                                 f"{self.share!r}")
        low, high = CODECS[self.codec]
        given = DEFAULT_QUALITY[self.codec] if self.quality is None else self.quality
        if not (isinstance(given, (list, tuple)) and len(given) == 2
                and all(isinstance(q, int) and not isinstance(q, bool) for q in given)
                and low <= given[0] <= given[1] <= high):
            raise ParameterError(f"view_coding quality for {self.codec} must be [lowest, "
                                 f"highest] integers within [{low}, {high}], got {given!r}")
        object.__setattr__(self, "quality", tuple(given))
        for name, value, bounds in (("hold", self.hold, (1, 60)), ("loops", self.loops, (2, 10))):
            if isinstance(value, bool) or not isinstance(value, int) \
                    or not bounds[0] <= value <= bounds[1]:
                raise ParameterError(f"view_coding {name} must be an integer in "
                                     f"[{bounds[0]}, {bounds[1]}], got {value!r}")

    @classmethod
    def from_value(cls, value: Any) -> ViewCoding | None:
        """From a recipe's or ``dataset.json``'s mapping (None: no coding)."""
        if value is None or isinstance(value, ViewCoding):
            return value
        if not isinstance(value, dict):
            raise ParameterError(f"view_coding must be a mapping (codec, share, quality), got "
                                 f"{value!r}")
        known = {"codec", "share", "quality", "hold", "loops"}
        unknown = sorted(set(value) - known)
        if unknown:
            raise ParameterError(f"unknown view_coding setting(s) {', '.join(unknown)}; known: "
                                 f"{', '.join(sorted(known))}")
        return cls(**value)

    @classmethod
    def parse(cls, text: str) -> ViewCoding:
        """``CODEC`` or ``CODEC:SHARE`` (a command line's), e.g. ``h264:0.5``."""
        codec, _, share = text.partition(":")
        try:
            value = float(share) if share else 0.5
        except ValueError:
            raise ParameterError(f"expected CODEC or CODEC:SHARE (e.g. h264:0.5), got "
                                 f"{text!r}") from None
        return cls(codec=codec, share=value)

    def require(self) -> ViewCoding:
        """Itself, once what its codec needs is known to be installed (before any work)."""
        from importlib.util import find_spec

        if self.codec == "h264" and find_spec("av") is None:
            raise ParameterError(_NEEDS_PYAV)
        return self

    def as_dict(self) -> dict[str, Any]:
        return {"codec": self.codec, "share": self.share, "quality": list(self.quality),
                "hold": self.hold, "loops": self.loops}


def code_views(left: np.ndarray, right: np.ndarray, coding: ViewCoding, seed: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """The stored 8-bit views ``(H, W, 3)`` or grey ``(H, W)``, coded if the draw of ``seed``
    falls in ``coding.share`` (else returned as they are)."""
    rng = np.random.default_rng((int(seed), 264))
    if rng.uniform() >= coding.share:
        return left, right
    quality = int(rng.integers(coding.quality[0], coding.quality[1] + 1))
    grey = left.ndim == 2
    views = np.stack([np.repeat(v[..., None], 3, axis=2) if grey else v for v in (left, right)])
    if coding.codec == "h264":
        coded = h264_round_trip(views, quality, hold=coding.hold, loops=coding.loops)
        coded = np.clip(np.rint(coded), 0, 255).astype(np.uint8)
    else:
        coded = np.stack([jpeg_round_trip(v, quality) for v in views])
    if grey:
        coded = coded[..., 1]
    return coded[0], coded[1]


def jpeg_round_trip(image: np.ndarray, quality: int) -> np.ndarray:
    """An 8-bit RGB image ``(H, W, 3)`` through a JPEG of ``quality`` (OpenCV, 4:2:0)."""
    ok, data = cv2.imencode(".jpg", image[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ParameterError("OpenCV could not write a JPEG")
    return cv2.imdecode(data, cv2.IMREAD_COLOR)[..., ::-1]


def h264_round_trip(views: np.ndarray, crf: int, *, hold: int = 4, loops: int = 2
                    ) -> np.ndarray:
    """8-bit RGB frames ``(N, H, W, 3)`` as one H.264 animation (libx264 through PyAV, 4:2:0,
    CRF ``crf``, preset medium) showing each frame ``hold`` times, ``loops`` times round; each
    frame back as the float32 mean ``(N, H, W, 3)`` (0-255) of its decoded copies after the
    first round. Odd sizes are padded by reflection for 4:2:0 and cut back."""
    try:
        import av
    except ImportError:
        raise ParameterError(_NEEDS_PYAV) from None
    count, height, width = views.shape[:3]
    padded = np.pad(views, ((0, 0), (0, height % 2), (0, width % 2), (0, 0)), mode="reflect")
    buffer = io.BytesIO()
    with av.open(buffer, "w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height = padded.shape[2], padded.shape[1]
        stream.pix_fmt = "yuv420p"
        stream.options = {"crf": str(int(crf)), "preset": "medium"}
        for _ in range(loops):
            for frame in padded:
                for _ in range(hold):
                    container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, "rgb24")))
        container.mux(stream.encode())
    buffer.seek(0)
    sums = np.zeros(padded.shape, np.float64)
    seen = np.zeros(count, np.int64)
    with av.open(buffer, "r") as container:
        for j, frame in enumerate(container.decode(video=0)):
            if j >= count * hold:  # after the first round
                k = (j // hold) % count
                sums[k] += frame.to_ndarray(format="rgb24")
                seen[k] += 1
    if not seen.all():
        raise ParameterError(f"the H.264 round trip returned too few frames ({int(seen.sum())})")
    return (sums / seen[:, None, None, None])[:, :height, :width].astype(np.float32)
