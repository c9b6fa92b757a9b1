"""Issue #77 item 4: how much of a network's width is in use on real DP views?

Per rectified layer of the base network (each ``nn.ReLU``, each up-convolution, the ConvLSTM's
hidden state), the share of its channels that are positive on at least ``--alive`` of the
pixels of the given real pairs, and the share of all activations that are positive. A ReLU
channel negative everywhere gives no gradient and carries nothing: a network whose coarse levels
are mostly such channels has lost the receptive field that strong blur needs, whatever its width.
With ``--ablate``, also the mean PSNR against each scene's ``target.png`` with the output of
each up-convolution zeroed in turn (coarsest first): how much each level's path carries; on a
DPDD dataset's test sequences (the state carried) the ablation alone. ``--cut mean`` replaces
that output by its mean over each image instead (per channel): a level that carries only a
constant offset, not what it sees, then costs nothing.

    python experiments/scripts/dead_units.py rdpd-light.v18 ../shared/data/canon-dp-real
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from torch import nn

from dualpixel import load_model
from dualpixel.data.radial import radial_distance
from dualpixel.io.images import read_rgb
from dualpixel.models.unet import _UpConv


def layers(net: nn.Module) -> dict[str, nn.Module]:
    """Name -> module whose output is rectified: ReLUs and up-convolutions, refiner left out."""
    found = {}
    for name, module in net.named_modules():
        if name.startswith("refiner"):
            continue
        if isinstance(module, (nn.ReLU, _UpConv)):
            found[name] = module
    return found


def _inputs(net: nn.Module, scene: Path) -> torch.Tensor:
    """The model's input for a scene's two views, ``(1, C_in, H, W)``."""
    left, right = (torch.from_numpy(read_rgb(scene / f"view{i}.png")).permute(2, 0, 1)[None]
                   for i in (0, 1))
    h, w = left.shape[-2:]
    radial = torch.from_numpy(radial_distance(h, w))[None, None]
    return net.spec.make_input(left.float(), right.float(), radial)


def _scene_scores(net: nn.Module, scenes: Path) -> float:
    """Mean PSNR of ``net`` over a folder of ``scene_*`` pairs with targets."""
    from dualpixel.evaluation.metrics import psnr

    scores = []
    for folder in sorted(scenes.glob("scene_*")):
        with torch.no_grad():
            out, _ = net.step(_inputs(net, folder))
        scores.append(psnr(out[0].permute(1, 2, 0).numpy(), read_rgb(folder / "target.png")))
    return float(np.mean(scores))


def _sequence_scores(net: nn.Module, dataset: Path) -> float:
    """Mean PSNR of ``net`` over a DPDD dataset's test sequences, the state carried."""
    from dualpixel.data.layout import discover_dp_dataset
    from dualpixel.training.trainer import validate

    return validate(net, discover_dp_dataset(dataset, "test"), torch.device("cpu"))[0]


def ablate(net: nn.Module, data: Path, cut: str = "zero") -> None:
    """Mean PSNR against the targets, whole and with each up-convolution's output zeroed (or,
    ``cut="mean"``, replaced by its per-image, per-channel mean): ``data`` a folder of
    ``scene_*`` pairs or a DPDD dataset (its test sequences)."""
    score = _scene_scores if any(data.glob("scene_*")) else _sequence_scores

    def replace(module, args, out):
        if cut == "zero":
            return torch.zeros_like(out)
        return out.mean((-2, -1), keepdim=True).expand_as(out)

    label = "zeroed" if cut == "zero" else "mean of"
    for name in ["none", *(f"upconvs.{i}" for i in range(len(net.upconvs)))]:
        handle = None
        if name != "none":
            handle = net.get_submodule(name).register_forward_hook(replace)
        try:
            print(f"{label} {name:10s} {score(net, data):.2f} dB", flush=True)
        finally:
            if handle is not None:
                handle.remove()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", help="a shipped tag or a .safetensors file")
    parser.add_argument("scenes", type=Path, help="folder of scene_*/view0.png, view1.png "
                        "(with --ablate also a DPDD dataset: its test sequences, ablation only)")
    parser.add_argument("--alive", type=float, default=0.001,
                        help="a channel is in use when positive on at least this share")
    parser.add_argument("--ablate", action="store_true",
                        help="also PSNR with each up-convolution's output zeroed in turn")
    parser.add_argument("--cut", choices=("zero", "mean"), default="zero",
                        help="with --ablate: zero the output, or replace it by its mean over "
                        "each image (per channel)")
    args = parser.parse_args()
    net = load_model(args.checkpoint, device="cpu").eval()
    if not any(args.scenes.glob("scene_*")):
        ablate(net, args.scenes, args.cut)
        return
    watched = layers(net)
    positive = {name: None for name in watched}
    totals = dict.fromkeys(watched, 0)

    def hook(name):
        def count(module, inputs, out):
            counts = (out > 0).sum(dim=(0, 2, 3), dtype=torch.float64)
            positive[name] = counts if positive[name] is None else positive[name] + counts
            totals[name] += out[:, 0].numel()
        return count

    handles = [m.register_forward_hook(hook(n)) for n, m in watched.items()]
    lstm = {"positive": None, "total": 0}
    for scene in sorted(args.scenes.glob("scene_*")):
        with torch.no_grad():
            _, state = net.step(_inputs(net, scene))
        if state is not None:
            hidden = state[0].abs() > 1e-3  # tanh-gated: in use where not ~0
            counts = hidden.sum(dim=(0, 2, 3), dtype=torch.float64)
            lstm["positive"] = counts if lstm["positive"] is None else lstm["positive"] + counts
            lstm["total"] += hidden[:, 0].numel()
    for handle in handles:
        handle.remove()
    if args.ablate:
        ablate(net, args.scenes, args.cut)
    print(f"{args.checkpoint} on {args.scenes}: channels in use (positive on >= {args.alive:.1%} "
          "of pixels) and positive activations, per rectified layer")
    print(f"{'layer':40s} {'channels':>9s} {'in use':>7s} {'positive':>9s}")
    rows = [(n, positive[n], totals[n]) for n in watched if positive[n] is not None]
    if lstm["positive"] is not None:
        rows.append(("lstm hidden (|h| > 1e-3)", lstm["positive"], lstm["total"]))
    for name, counts, total in rows:
        share = (counts / max(total, 1)).numpy()
        print(f"{name:40s} {share.size:9d} {np.mean(share >= args.alive):7.0%} "
              f"{share.mean():9.1%}")


if __name__ == "__main__":
    main()
