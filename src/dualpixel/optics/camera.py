"""A camera's DP blur model as a file (``camera.json``): what ``dualpixel calibrate camera``
measures (:mod:`dualpixel.calibration.camera`) and what synthesis, recipes and the API read
(``synth --camera``, ``synthesize(camera=)``, ``camera:``). The package ships some by name
(:mod:`dualpixel.cameras`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from dualpixel.errors import InputFileError, ParameterError, check_integer, check_range
from dualpixel.io.documents import read_mapping
from dualpixel.optics.crosstalk import check_disparity_falloff, check_disparity_ratio
from dualpixel.optics.psf import PSFParams
from dualpixel.optics.tone import check_light

__all__ = ["CAMERA_FORMAT", "DPCamera", "load_camera"]

CAMERA_FORMAT = "dualpixel-camera-1"


@dataclass(frozen=True)
class DPCamera:
    """A camera's DP blur model (``camera.json``; ``dualpixel synth --camera``).

    Args:
        name: a label.
        width: width (px) of the frames the blur figures below refer to.
        disparity_ratio: per channel (R, G, B), the fraction of our model's disparity the views
            keep at the same blur (1: the paper's model).
        psf: the PSF shape of Eq. 2-4 that fits best.
        noise_std: noise std of the views, [0, 1] units (Immerkaer's estimator).
        coc_percentiles: |CoC radius| px at ``width`` over the textured blocks (p10 ... p90).
        blocks: how many blocks the estimate rests on.
        light: where the views are blurred (:mod:`dualpixel.optics.tone`): "linear" (linear
            light, then the sRGB curve) or "encoded" (the stored values, the paper's model).
        disparity_falloff: how the disparity ratio falls from the middle of the frame to its
            left and right sides (:mod:`dualpixel.optics.crosstalk`; 0: the same everywhere).
    """

    name: str
    width: int
    disparity_ratio: tuple[float, float, float]
    psf: PSFParams
    noise_std: float = 0.0
    coc_percentiles: dict[str, float] = field(default_factory=dict)
    blocks: int = 0
    light: str = "encoded"
    disparity_falloff: float = 0.0

    def __post_init__(self) -> None:
        check_light(self.light)
        check_range("width", self.width, 1)
        check_disparity_ratio(self.disparity_ratio)
        check_disparity_falloff(self.disparity_falloff)
        check_range("noise_std", self.noise_std, 0.0, 1.0)

    def to_dict(self) -> dict:
        return {"format": CAMERA_FORMAT, "name": self.name, "width": self.width,
                "disparity_ratio": [round(float(v), 4) for v in self.disparity_ratio],
                "psf": self.psf.as_dict(), "noise_std": round(float(self.noise_std), 6),
                "coc_percentiles": self.coc_percentiles, "blocks": self.blocks,
                **({} if self.light == "encoded" else {"light": self.light}),
                **({} if not self.disparity_falloff
                   else {"disparity_falloff": round(float(self.disparity_falloff), 4)})}

    def save(self, path: str | Path) -> Path:
        """Write ``camera.json`` atomically."""
        from dualpixel.io.atomic import atomic_path

        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return Path(path)

    @classmethod
    def from_dict(cls, data: dict, source: str | Path = "camera") -> DPCamera:
        """Build from a dict as :meth:`to_dict` writes it; errors name ``source`` and the field."""
        if not isinstance(data, dict) or data.get("format") != CAMERA_FORMAT:
            raise InputFileError(source, f"not a dualpixel camera file (expected \"format\": "
                                         f"\"{CAMERA_FORMAT}\")")
        required = ("name", "width", "disparity_ratio", "psf")
        missing = [k for k in required if k not in data]
        if missing:
            raise InputFileError(source, f"camera field(s) missing: {', '.join(missing)}")
        known = {"format", *required, "noise_std", "coc_percentiles", "blocks", "light",
                 "disparity_falloff"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise InputFileError(source, f"unknown camera field(s): {', '.join(unknown)}")
        try:
            psf = data["psf"]
            if not isinstance(psf, dict) or set(psf) != {"n", "alpha", "beta", "kappa"}:
                raise ParameterError("psf must hold n, alpha, beta and kappa")
            ratio = data["disparity_ratio"]
            if not isinstance(ratio, list):
                raise ParameterError("disparity_ratio must be a list of 3 numbers")
            percentiles = data.get("coc_percentiles", {})
            if not isinstance(percentiles, dict):
                raise ParameterError("coc_percentiles must map p10 .. p90 to radii")
            return cls(name=str(data["name"]),
                       width=check_integer("width", data["width"], 1, 65536),
                       disparity_ratio=check_disparity_ratio(ratio),  # type: ignore[arg-type]
                       psf=PSFParams(**{k: check_range(f"psf.{k}", v) for k, v in psf.items()}),
                       noise_std=check_range("noise_std", data.get("noise_std", 0.0), 0.0, 1.0),
                       coc_percentiles={str(k): check_range(f"coc_percentiles.{k}", v, 0.0)
                                        for k, v in percentiles.items()},
                       blocks=check_integer("blocks", data.get("blocks", 0)),
                       light=str(data.get("light", "encoded")),
                       disparity_falloff=check_disparity_falloff(
                           data.get("disparity_falloff", 0.0)))
        except (ParameterError, TypeError, ValueError) as error:
            raise InputFileError(source, f"bad camera field: {error}") from None


def load_camera(path: str | Path) -> DPCamera:
    """Read a ``camera.json`` written by ``dualpixel calibrate camera``, or a shipped camera
    by name (:mod:`dualpixel.cameras`: ``canon-840``, ``pixel4``, ...)."""
    from dualpixel.cameras import camera_names, shipped_camera

    if not Path(path).exists():
        path = shipped_camera(str(path)) or path
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "camera file not found (the shipped cameras: "
                                   f"{', '.join(camera_names())})")
    return DPCamera.from_dict(read_mapping(path, "camera file"), path)
