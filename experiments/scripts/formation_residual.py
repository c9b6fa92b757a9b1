"""A target-free measure tried for issue #77 item 2: how well a model's output, blurred by the
left and right DP PSFs at each block's radius, explains the two views (the formation residual).

Per 64-px block the signed CoC radius is the one whose PSFs best satisfy the cross-convolution
identity ``L * H_r = R * H_l`` (Punnappurath et al., ICCP 2020); the output ``S`` is then blurred
by ``H_l`` and ``H_r`` at that radius and, after one least-squares gain per block (a target
captured at another exposure), compared with ``L`` and ``R``: the residual over the views' own
detail, over defocused (|r| >= 1 px), textured blocks. Linear light, grey, the paper's PSF shape.

Read as the plan in docs/log/2026-12-01-photographic-scenes.md says: it is a decision measure only
if a sharp target scores below the blurred input on the dev scenes, and it ranks v15 < v12 < wide
(lower is better) as the real photographs rank them.

    python experiments/scripts/formation_residual.py [OUT]    # default runs/formation
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch

import dualpixel
from dualpixel.io.images import read_rgb
from dualpixel.optics.psf import dp_psf
from dualpixel.optics.tone import srgb_to_linear_array
from dualpixel.synthesis.convolution import convolve_same

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"
MODELS = ["rdpd-light.v15", "rdpd-light.v12", "rdpd-wide.v2"]
RADII = sorted({0.0, *[s * r for s in (-1, 1) for r in (0.5, 1, 1.5, 2, 3, 4, 5, 6, 8, 10, 12,
                                                         15)]})
PATCH = 64


def _blocks(values: torch.Tensor) -> np.ndarray:
    rows, cols = values.shape[-2] // PATCH, values.shape[-1] // PATCH
    cut = values[..., : rows * PATCH, : cols * PATCH]
    return cut.reshape(*cut.shape[:-2], rows, PATCH, cols, PATCH).sum(dim=(-3, -1)).numpy()


def _kernels(radius: float) -> torch.Tensor:
    k = dp_psf(radius, dtype=torch.float64)
    return 2.0 * torch.stack((k.left, k.right))


def block_radii(left: torch.Tensor, right: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """Per block the radius of least relative cross-convolution error, and textured blocks."""
    best = radius_of = None
    for radius in RADII:
        blurred = convolve_same(torch.stack((left, right)), _kernels(radius))
        l_hr, r_hl = blurred[1, 0], blurred[0, 1]
        error = _blocks((l_hr - r_hl) ** 2)
        energy = _blocks((l_hr - l_hr.mean()) ** 2 + (r_hl - r_hl.mean()) ** 2)
        relative = error / np.maximum(energy, 1e-12)
        if best is None:
            best, radius_of = relative, np.full(relative.shape, radius)
        else:
            radius_of = np.where(relative < best, radius, radius_of)
            best = np.minimum(relative, best)
    mean = 0.5 * (left + right)
    gradient = torch.diff(mean, dim=1)[:-1] ** 2 + torch.diff(mean, dim=0)[:, :-1] ** 2
    textured = _blocks(torch.nn.functional.pad(gradient, (0, 1, 0, 1))) / PATCH**2 > 2e-5
    return radius_of, textured


def residual(left, right, output, radius_of, textured) -> float:
    """Defocused textured blocks: min over a per-block gain of the squared error of the blurred
    output against both views, over the views' squared detail."""
    error = np.zeros(radius_of.shape)
    for radius in np.unique(radius_of):
        blurred = convolve_same(output[None], _kernels(float(radius)))[:, 0]
        views = torch.stack((left, right))
        cross = _blocks((blurred * views).sum(0))
        power = _blocks((blurred**2).sum(0))
        own = _blocks((views**2).sum(0))
        fitted = own - cross**2 / np.maximum(power, 1e-12)  # after the best gain per block
        error = np.where(radius_of == radius, fitted, error)
    detail = _blocks(((torch.stack((left, right)) - left.mean()) ** 2).sum(0))
    mask = textured & (np.abs(radius_of) >= 1.0)
    return float(error[mask].sum() / max(detail[mask].sum(), 1e-12))


def _grey_linear(image: np.ndarray) -> torch.Tensor:
    image = np.asarray(image, np.float64)
    image = image.mean(axis=2) if image.ndim == 3 else image
    return torch.from_numpy(np.asarray(srgb_to_linear_array(image), np.float64))


def pairs():
    """(name, left, right, extras) of the dev Canon scenes (target, input) and dp-real-nogt."""
    for scene in sorted((SHARED / "canon-dp-real").glob("scene_*")):
        yield (f"dev/{scene.name}", read_rgb(scene / "view0.png"), read_rgb(scene / "view1.png"),
               {k: read_rgb(scene / f"{k}.png") for k in ("target", "input")})
    for folder in sorted(p for p in (SHARED / "dp-real-nogt").iterdir() if p.is_dir()):
        left, right = (read_rgb(folder / f"{v}.png") for v in ("left", "right"))
        yield folder.name, left, right, {"input": 0.5 * (left + right)}


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    results_path = out / "residuals.json"
    results = json.loads(results_path.read_text()) if results_path.is_file() else {}
    for name, left, right, extras in pairs():
        if name in results:
            continue
        lin_l, lin_r = _grey_linear(left), _grey_linear(right)
        radius_of, textured = block_radii(lin_l, lin_r)
        row = {k: residual(lin_l, lin_r, _grey_linear(v), radius_of, textured)
               for k, v in extras.items()}
        for model in MODELS:
            output = dualpixel.deblur(left, right, model=model, device="cpu")
            row[model] = residual(lin_l, lin_r, _grey_linear(output), radius_of, textured)
        row["blocks"] = int((textured & (np.abs(radius_of) >= 1)).sum())
        results[name] = row
        results_path.write_text(json.dumps(results, indent=1))
        print(name, {k: round(v, 4) for k, v in row.items()}, flush=True)
    groups = {"dev Canon": [k for k in results if k.startswith("dev/")],
              "Pixel": [k for k in results if k.startswith("pixel")],
              "Canon (nogt)": [k for k in results if k.startswith(("canon", "sdirt"))]}
    print("| pairs | n | input | target | " + " | ".join(MODELS) + " | v15 < v12 < wide |")
    print("|---|---|---|---|" + "---|" * (len(MODELS) + 1))
    for group, names in groups.items():
        if not names:
            continue
        mean = {k: np.mean([results[n][k] for n in names]) for k in ["input", *MODELS]}
        target = (f"{np.mean([results[n]['target'] for n in names]):.4f}"
                  if "target" in results[names[0]] else "-")
        ok = mean[MODELS[0]] < mean[MODELS[1]] < mean[MODELS[2]]
        print(f"| {group} | {len(names)} | {mean['input']:.4f} | {target} | "
              + " | ".join(f"{mean[m]:.4f}" for m in MODELS) + f" | {'yes' if ok else 'no'} |")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "runs" / "formation")
