"""What an adaptation changed: the start and the adapted model side by side on the camera's
held-out synthetic frames (PSNR) and on the photographs themselves (the target-free checks of
:mod:`dualpixel.evaluation.target_free` and the formation residuals of
:mod:`dualpixel.training.formation`), written as ``report.md`` and ``report.json``.

The formation residual is reported, not decided by: a blurrier output fits the views about as
well as the sharp image where the measured blur is off (``docs/formation.md``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dualpixel.data.views import BlurMap
from dualpixel.optics.camera import DPCamera

__all__ = ["formation_residual", "write_report"]


def formation_residual(output: np.ndarray, left: np.ndarray, right: np.ndarray,
                       blur: BlurMap, camera: DPCamera) -> dict[str, float]:
    """The formation loss's two terms (mean squared, stored values or linear light as the
    camera's) of a whole ``output`` ``(H, W, 3)`` against its views, over the pair's blocks."""
    from dualpixel.training.formation import FormationLoss

    height, width = left.shape[:2]

    def tensor(image: np.ndarray) -> torch.Tensor:
        image = np.broadcast_to(np.atleast_3d(image), (height, width, 3))  # a read-only view
        return torch.tensor(image, dtype=torch.float32).permute(2, 0, 1)[None]

    maps = blur.pixel_maps(height, width)
    item = {"left": tensor(left), "right": tensor(right),
            **{k: torch.from_numpy(v)[None] for k, v in zip(
                ("radius", "side", "blurred", "in_focus"), maps)}}
    with torch.no_grad():
        _, parts = FormationLoss(camera)(tensor(output), item)
    return {k: float(v) for k, v in parts.items()}


def _val_psnr(checkpoint: str | Path, val: str, device: str) -> float:
    from dualpixel.data.layout import discover_dp_dataset
    from dualpixel.device import resolve_device
    from dualpixel.models.checkpoint import load_model
    from dualpixel.training.trainer import validate

    target = resolve_device(device)
    model = load_model(checkpoint, device=target).float()
    return validate(model, discover_dp_dataset(val, "test"), target)[0]


def _pair_names(pairs: Sequence[tuple[str, ...]]) -> list[str]:
    """Each pair's folder name, with its parent's where two folders share a name (the same
    scenes at two resolutions)."""
    folders = [Path(pair[0]).parent for pair in pairs]
    names = [folder.name for folder in folders]
    return [f"{folder.parent.name}/{name}" if names.count(name) > 1 else name
            for folder, name in zip(folders, names)]


def write_report(output: Path, pairs: Sequence[tuple[str, str, np.ndarray, np.ndarray]],
                 start: Path, adapted: Path, maps: Sequence[BlurMap], camera: DPCamera, val: str,
                 *, device: str = "auto", progress: bool = False) -> dict[str, Any]:
    """Measure the start and the adapted model on ``pairs`` (``(left path, right path, left,
    right)``, :func:`~dualpixel.adaptation.finetune.read_views`; grey views are given to the
    models and the checks as one channel) and on the held-out set ``val``; returns the figures
    also written to ``output/report.json``."""
    from dualpixel.calibration.target_free import grey_as_one_channel
    from dualpixel.evaluation.target_free import check_deblurred, markdown_table, model_methods
    from dualpixel.io.atomic import atomic_path
    from dualpixel.progress import progress_bar

    names = {"start": str(start), "adapted": str(adapted)}
    # one method per checkpoint, each with the output settings it carries
    methods = dict(zip(names, model_methods(names.values(), device=device).values(),
                       strict=True))
    rows, residuals = [], {label: [] for label in names}
    steps = progress_bar(total=len(pairs) * len(names), desc="adapt report", enabled=progress)
    with steps:
        for (_, _, left, right), blur, pair in zip(pairs, maps, _pair_names(pairs)):
            left, right = grey_as_one_channel(left, right)
            for label, method in methods.items():
                deblurred = method(left, right)
                report = check_deblurred(left, right, deblurred)
                rows.append({"pair": pair, "method": label, **report.as_dict()})
                residuals[label].append(formation_residual(deblurred, left, right, blur, camera))
                steps.update()
    figures: dict[str, Any] = {"pairs": len(pairs), "camera": camera.to_dict()}
    for label, checkpoint in names.items():
        terms = {}
        for key in ("formation", "in_focus"):
            values = [r[key] for r in residuals[label] if key in r]
            terms[key] = float(np.mean(values)) if values else None
        figures[label] = {"checkpoint": checkpoint, "camera_val_psnr": _val_psnr(
            checkpoint, val, device), "formation_residual": terms["formation"],
            "in_focus_residual": terms["in_focus"]}
    figures["target_free"] = rows
    with atomic_path(output / "report.json") as tmp:
        tmp.write_text(json.dumps(figures, indent=1, default=float) + "\n")
    lines = [f"# Adaptation to camera {camera.name!r}", "",
             f"{len(pairs)} DP pairs (in `{Path(pairs[0][0]).parent.parent}`, ...); start "
             f"`{start.name}`, adapted "
             f"`{adapted.name}`.", "",
             "| | held-out synthetic frames of the camera, PSNR dB | formation residual "
             "(x1e4) | in-focus residual (x1e4) |", "|---|---|---|---|"]
    for label in names:
        entry = figures[label]
        cells = [f"{entry['camera_val_psnr']:.2f}"] + [
            "-" if entry[k] is None else f"{1e4 * entry[k]:.3f}"
            for k in ("formation_residual", "in_focus_residual")]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += ["", "The formation residual is reported, not a goal: a blurrier output fits the "
              "views about as well where the measured blur is off.", "",
              "## Target-free checks on the photographs", "", markdown_table(rows)]
    with atomic_path(output / "report.md") as tmp:
        tmp.write_text("\n".join(lines))
    return figures
