"""Does more width help the light RDPD quickly? (issue #11; MODEL_CARD.md "What limits the light
model".)

Widens the finer encoder/decoder levels of a trained checkpoint without changing what it computes
(Net2Net-style: each new unit gets fresh input weights and zero output weights), then trains the
original or the widened network on the same 8-crop batches at a constant rate with the per-patch
log loss, and writes the loss per iteration. Run once per network and compare the two files:

    .venv/bin/python scripts/probe_width.py base 250 runs/exp/probe_base.json
    .venv/bin/python scripts/probe_width.py wide 250 runs/exp/probe_wide.json
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np
import torch

from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset
from dualpixel.models import load_model
from dualpixel.models.unet import DeblurNet
from dualpixel.training.losses import DeblurLoss
from dualpixel.weights import resolve_checkpoint


def _conv_maps(net: DeblurNet, widths: tuple[int, ...]) -> dict[str, tuple[list[int], list[int]]]:
    """Per convolution of ``net`` (old widths): where its output and input channels go when the
    encoder levels get ``widths`` (the decoder's input is [skip, up-convolution])."""
    old = net.shape.encoder
    same = lambda n: list(range(n))  # noqa: E731
    maps: dict[str, tuple[list[int], list[int]]] = {}
    cin = net.shape.in_channels
    for level, c in enumerate(old):
        maps[f"encoders.{level}.0"] = (same(c), same(cin))
        maps[f"encoders.{level}.2"] = (same(c), same(c))
        cin = c
    cin = net.shape.bottleneck
    for k, level in enumerate(reversed(range(len(old)))):
        c, wide = old[level], widths[level]
        maps[f"upconvs.{k}.conv"] = (same(c), same(cin))
        maps[f"decoders.{k}.0"] = (same(c), same(c) + [wide + i for i in range(c)])
        maps[f"decoders.{k}.2"] = (same(c), same(c))
        cin = c
    maps["head.0"] = (same(3), same(cin))
    return maps


def widen(net: DeblurNet, widths: tuple[int, ...]) -> DeblurNet:
    """``net`` with encoder widths ``widths`` (the coarsest must stay), computing the same."""
    if widths[-1] != net.shape.encoder[-1] or len(widths) != len(net.shape.encoder):
        raise ValueError("only the finer levels can be widened")
    wide = DeblurNet(replace(net.shape, encoder=widths))
    wide.spec, wide.width = net.spec, net.width
    state = wide.state_dict()
    old = net.state_dict()
    maps = _conv_maps(net, widths)
    for name, value in old.items():
        module, _, kind = name.rpartition(".")
        if module not in maps:
            state[name] = value  # bottleneck, ConvLSTM, last 1x1 conv: unchanged sizes
            continue
        outs, ins = maps[module]
        if kind == "bias":
            state[name][outs] = value
            continue
        weight = state[name]
        weight[:, [i for i in range(weight.shape[1]) if i not in ins]] = 0.0  # new inputs: unused
        weight[np.ix_(outs, ins)] = value
    wide.load_state_dict(state)
    return wide


def _batches(data: DPPatchDataset, iterations: int, size: int = 8, seed: int = 123):
    rng = np.random.default_rng(seed)
    for it in range(iterations):
        items = [data[(int(rng.integers(len(data))), it * size + j)] for j in range(size)]
        yield {key: torch.stack([item[key] for item in items]) for key in items[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("network", choices=["base", "wide"])
    parser.add_argument("iterations", type=int)
    parser.add_argument("output")
    parser.add_argument("--checkpoint", default="rdpd-light")
    parser.add_argument("--widths", default="24,48,96,128")
    parser.add_argument("--data", default="runs/data/mix-synth-train")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    base = load_model(resolve_checkpoint(args.checkpoint))
    widths = tuple(int(w) for w in args.widths.split(","))
    net = widen(base, widths) if args.network == "wide" else base
    data = DPPatchDataset(discover_dp_dataset(args.data, "train"),
                          PatchConfig(patch_size=128, frames=1, flips=True))
    probe = next(_batches(data, 1, seed=7))
    x = base.spec.make_input(probe["left"], probe["right"], probe["radial"])
    with torch.no_grad():
        change = (net.eval()(x)[0] - base.eval()(x)[0]).abs().max().item()
    print(f"{args.network}: {sum(p.numel() for p in net.parameters()):,} parameters, "
          f"largest output change from widening {change:.1e}")
    loss_fn = DeblurLoss(reduction="log")
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-4)
    net.train()
    losses, start = [], time.time()
    for it, batch in enumerate(_batches(data, args.iterations)):
        out, _ = net(net.spec.make_input(batch["left"], batch["right"], batch["radial"]))
        loss, _ = loss_fn(out.flatten(0, 1), batch["target"].flatten(0, 1))
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
        if (it + 1) % 50 == 0:
            print(f"{args.network} {it + 1}: loss {np.mean(losses[-50:]):.4f} dB, "
                  f"{(time.time() - start) / (it + 1):.2f} s/iteration", flush=True)
    with open(args.output, "w") as handle:
        json.dump({"network": args.network, "widths": widths, "losses": losses,
                   "seconds": time.time() - start}, handle)


if __name__ == "__main__":
    main()
