"""Synthetic frames stored as raw values, trained on as ``dualpixel deblur`` feeds raw views.

A synthetic dataset made with ``encoding: linear`` stores its views and target as a raw sensor
does (a black level plus the light times an exposure gain, :func:`~dualpixel.optics.tone.
linear_to_raw`). A user's raw views reach the model through ``--encoding linear``
(:func:`~dualpixel.inference.encoding.to_model`: black level off, divided by the span to the white
level, sRGB-encoded). The training setting ``raw_views`` says which of the two a model is trained
on: ``"stored"`` (the values as the files hold them, read as display values: how the shipped
recipes trained) or ``"model"`` (each crop's views and target through ``to_model``, white level
at full scale, at the exposure the linear mode would give the crop (:meth:`~dualpixel.inference.
encoding.ViewEncoding.exposed`), so the loss is taken on what the model gives a user of the
linear mode).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualpixel.data.layout import DPSequence
from dualpixel.errors import InputFileError
from dualpixel.inference.encoding import ViewEncoding, to_model
from dualpixel.io.documents import read_mapping
from dualpixel.names import RAW_VIEWS

__all__ = ["RAW_VIEWS", "RawViewsAsModel", "StoredRawViews", "as_model", "raw_views_transform",
           "stored_black_level"]


def stored_black_level(root: str | Path) -> float | None:
    """The black level (a fraction of full scale) of a synthetic dataset folder stored as raw
    values (its ``dataset.json`` says ``encoding: linear``); None for display values or a
    folder ``synth`` did not make."""
    path = Path(root) / "dataset.json"
    if not path.is_file():
        return None
    config = read_mapping(path, "synthetic dataset description", syntax="json").get("config")
    if not isinstance(config, dict) or config.get("encoding") != "linear":
        return None
    black = config.get("black_level")
    if not isinstance(black, int | float) or not 0.0 <= black < 1.0:
        raise InputFileError(path, f"encoding linear needs a black_level in [0, 1), got {black!r}")
    return float(black)


@dataclass(frozen=True)
class RawViewsAsModel:
    """The :class:`~dualpixel.data.dataset.DPPatchDataset` transform of ``raw_views: model``.

    ``roots``: ``(dataset folder, black level)`` of every raw-stored folder; crops of sequences
    under none of them pass unchanged.
    """

    roots: tuple[tuple[Path, float], ...]

    def black_level(self, sequence: DPSequence) -> float | None:
        first = Path(sequence.frames[0].left).resolve()
        return next((black for root, black in self.roots if first.is_relative_to(root)), None)

    def __call__(self, sequence: DPSequence,
                 images: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``images`` ``{left, right[, target]}`` ``(h, w, 3)`` stored values in [0, 1] as the
        model takes them (display values), for a raw-stored sequence; others unchanged."""
        black = self.black_level(sequence)
        return images if black is None else as_model(images, black)


@dataclass(frozen=True)
class StoredRawViews:
    """The ``raw_views: model`` transform of a source whose every sequence is raw-stored with
    ``black`` (a fraction of full scale): an on-the-fly source of ``encoding: linear``."""

    black: float

    def __call__(self, sequence: DPSequence,
                 images: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return as_model(images, self.black)


def as_model(images: dict[str, np.ndarray], black: float) -> dict[str, np.ndarray]:
    """Raw-stored ``images`` ``{left, right[, target]}`` ``(h, w, 3)`` (black level ``black``,
    white level full scale) as the linear mode hands them to the model: at the exposure it gives
    the views (:meth:`~dualpixel.inference.encoding.ViewEncoding.exposed`), the target alike."""
    encoding = ViewEncoding("linear", black, 1.0).exposed(images["left"], images["right"],
                                                          check=False)
    out = dict(images)
    out["left"], out["right"] = to_model(images["left"], images["right"], encoding)
    if "target" in images:
        out["target"] = to_model(images["target"], images["target"], encoding)[0]
    return out


def raw_views_transform(roots: str | list[str] | None, raw_views: str) -> RawViewsAsModel | None:
    """The transform for the dataset folders ``roots`` under the setting ``raw_views``: None
    for ``"stored"`` or when no folder is raw-stored."""
    if raw_views == "stored" or roots is None:
        return None
    folders = [roots] if isinstance(roots, str) else roots
    found = [(Path(root).resolve(), stored_black_level(root)) for root in folders]
    raw = tuple((root, black) for root, black in found if black is not None)
    return RawViewsAsModel(raw) if raw else None
