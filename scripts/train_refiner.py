"""Train a refiner (``dualpixel.models.refiner``) on top of a frozen network (by default stage 7 of
the default model) and write the refined network as one checkpoint (issue #11; MODEL_CARD.md,
stage 8).

The first stage is never trained, so its output for each batch is computed without gradients
and the refiner alone is optimised: Adam, one-cycle rate (5 % warm-up to ``--lr``, cosine to
zero), the per-patch log loss, 4 random 256-px crops per batch from the training frames. Logs
the loss of the refined and of the first-stage output on the same batches (their difference is
what the refiner adds), saves the refiner every 300 iterations, and at the end writes
``OUT.safetensors`` (float16, the first stage's weights and the refiner's) and scores the first
``--eval`` held-out frames.

    .venv/bin/python scripts/train_refiner.py 2400 runs/refiner/stage8  # the shipped stage 8

For longer, resumable runs use the trainer instead (``refiner`` and ``freeze_first_stage`` in
the config: ``configs/rdpd-light-refiner-cpu.yaml``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset
from dualpixel.data.layout import read_frame
from dualpixel.evaluation.metrics import psnr
from dualpixel.inference.deblur import frame_tensor
from dualpixel.models import load_model, load_weights, read_metadata, save_model
from dualpixel.models.checkpoint import build_from_metadata
from dualpixel.models.refiner import Refiner
from dualpixel.models.unet import DeblurNet
from dualpixel.training.losses import DeblurLoss
from dualpixel.weights import resolve_checkpoint


def batches(data: DPPatchDataset, count: int, size: int, seed: int):
    """``count`` batches of ``size`` single-frame crops ``(B, C, H, W)``, reproducibly."""
    rng = np.random.default_rng(seed)
    for it in range(count):
        items = [data[(int(rng.integers(len(data))), it * size + j)] for j in range(size)]
        yield {k: torch.stack([i[k] for i in items])[:, 0] for k in items[0]}


def first_stage(net: DeblurNet, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, ...]:
    """The network input ``(B, 7, H, W)`` and the frozen first stage's output ``(B, 3, H, W)``."""
    x = net.spec.make_input(batch["left"], batch["right"], batch["radial"])
    with torch.no_grad():
        return x, net.step(x)[0]


def evaluate(net: DeblurNet, refiner: Refiner, data: str, count: int) -> np.ndarray:
    """Per held-out frame: PSNR of the input, the first stage and the refined output (dB)."""
    frames = [f for s in discover_dp_dataset(data, "test") for f in s.frames][:count]
    rows = []
    image = lambda t: t[0].permute(1, 2, 0).numpy()  # noqa: E731  (1, 3, H, W) -> (H, W, 3)
    for frame in frames:
        views = read_frame(frame)
        x = frame_tensor(net, views["left"], views["right"])
        with torch.no_grad():
            first = net.step(x)[0]
            refined = refiner(x, first)
        target = views["target"]
        rows.append((psnr((views["left"] + views["right"]) / 2, target),
                     psnr(image(first), target), psnr(image(refined), target)))
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("iterations", type=int)
    parser.add_argument("out", help="output prefix (OUT.log lines on stdout, OUT.N.pt, OUT.json, "
                                    "OUT.safetensors)")
    parser.add_argument("--checkpoint", default="rdpd-light-stage7",
                        help="the first stage: a network without a refiner")
    parser.add_argument("--widths", default="32,64,128")
    parser.add_argument("--lr", type=float, default=5e-4)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--patch", type=int, default=256)
    parser.add_argument("--data", default="runs/data/mix-synth-train")
    parser.add_argument("--test-data", default="runs/data/mix-synth-test")
    parser.add_argument("--eval", type=int, default=16)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    if args.iterations < 4:
        parser.error("give at least 4 iterations (the rate warms up, then anneals)")
    torch.set_num_threads(args.threads)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    source = resolve_checkpoint(args.checkpoint)
    torch.manual_seed(0)  # before load_model, whose network construction draws from it
    net = load_model(source).eval()
    if net.refiner is not None:
        parser.error(f"--checkpoint {args.checkpoint} has a refiner already; give its first stage")
    widths = tuple(int(w) for w in args.widths.split(","))
    refiner = Refiner(net.shape.in_channels, widths)
    print(f"refiner {sum(p.numel() for p in refiner.parameters()):,} parameters", flush=True)
    data = DPPatchDataset(discover_dp_dataset(args.data, "train"),
                          PatchConfig(patch_size=args.patch, frames=1, flips=True,
                                      min_sharpness=0.01), cache=True)
    loss_fn = DeblurLoss(reduction="log")
    optimizer = torch.optim.Adam(refiner.parameters(), lr=args.lr)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimizer, args.lr, total_steps=args.iterations,
        pct_start=min(0.5, max(0.05, 4 / args.iterations)))
    log, started = [], time.time()
    for it, batch in enumerate(batches(data, args.iterations, args.batch, 123)):
        x, first = first_stage(net, batch)
        loss, _ = loss_fn(refiner(x, first), batch["target"])
        with torch.no_grad():
            first_loss, _ = loss_fn(first, batch["target"])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        schedule.step()
        log.append((loss.item(), first_loss.item()))
        if (it + 1) % 300 == 0:
            torch.save(refiner.state_dict(), f"{args.out}.{it + 1}.pt")
        if (it + 1) % 50 == 0:
            d = np.array(log[-50:])
            gain = d[:, 0] - d[:, 1]
            print(f"{it + 1}: loss {d[:, 0].mean():.3f} first stage {d[:, 1].mean():.3f} "
                  f"difference {gain.mean():+.4f} +- {gain.std() / np.sqrt(50):.4f} dB, "
                  f"{(time.time() - started) / (it + 1):.2f} s/iteration", flush=True)
    refiner.eval()
    write_refined(net, refiner, source, f"{args.out}.safetensors", vars(args))
    rows = evaluate(net, refiner, args.test_data, args.eval)
    print("held-out input / first stage / refined (dB):", np.round(rows.mean(0), 3))
    with open(f"{args.out}.json", "w") as handle:
        json.dump({"log": log, "eval": rows.tolist()}, handle)


def write_refined(net: DeblurNet, refiner: Refiner, source: str | Path, path: str,
                  recipe: dict) -> None:
    """One float16 checkpoint: the first stage ``source`` and the trained ``refiner``."""
    meta = read_metadata(source)
    refined = build_from_metadata(meta, refiner=refiner.widths)
    load_weights(refined, source, first_stage_only=True)
    refined.refiner.load_state_dict(refiner.state_dict())
    refined.temporal = net.temporal
    save_model(path, refined, dtype=torch.float16,
               extra={"first_stage": meta["extra"], "refiner_recipe": recipe,
                      "source": "scripts/train_refiner.py"})


if __name__ == "__main__":
    main()
