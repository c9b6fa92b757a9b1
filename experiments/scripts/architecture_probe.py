"""Two network classes trained alike from nothing (issue #77, item 4): the default's
``rdpd-light`` (RDPD at width 0.5 with its refiner) against ``dpnaf-light`` (the same U-Net with
NAF-block levels, :mod:`dualpixel.models.naf`: a third of the arithmetic, about the same time per
training step on this CPU). Which class learns more from the same photographic data decides
which one a long run (a lent GPU, or the CPU across sessions) should scale.

Both arms: random weights, the photographic recipe's seven on-the-fly cameras (the same crops and
draws, from the v17 run's data folder), ``--epochs`` x ``--iterations`` of 8 crops of 256 px,
learning rate 2e-4 cosine, EMA 0.999, the recipe's loss. Then scored by their best epoch: the seven
cameras' clean held-out frames (the recipe's validation sets) and the dev Canon scenes at both
resolutions (`dualpixel eval`). Resumable (a rerun continues the arm's training and skips what
is scored).

    python experiments/scripts/architecture_probe.py ARM OUT [--data runs/rdpd-light-photographs]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import torch

from dualpixel.models.checkpoint import load_model
from dualpixel.training import load_config, train
from dualpixel.training.raw_views import raw_views_transform
from dualpixel.training.trainer import _discover, has_checkpoint, validate

#: The arms: the architecture's build settings, as a training config takes them.
ARMS = {
    "rdpd-light": {"model": "rdpd", "width": 0.5, "residual": True, "refiner": [32, 64, 128]},
    "dpnaf-light": {"model": "dpnaf", "width": 0.5, "residual": True, "refiner": None},
}
DEV = ("canon-dp-real", "canon-dp-real-hd")


def held_out_psnr(checkpoint: Path, family_config: Path) -> float:
    """Mean PSNR (dB) over the seven cameras' held-out frames, as the recipe validates."""
    config = load_config(family_config)
    sequences = _discover(config.val_data, config.val_split)
    transform = raw_views_transform(config.val_data, config.raw_views)
    model = load_model(checkpoint, device="cpu").float()
    return float(validate(model, sequences, torch.device("cpu"), transform)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("arm", choices=tuple(ARMS))
    parser.add_argument("output", type=Path)
    parser.add_argument("--data", type=Path, default=Path("runs/rdpd-light-photographs"))
    parser.add_argument("--epochs", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=600)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    family = args.data / "phases" / "family" / "config.yaml"
    run = args.output / args.arm
    config = load_config(family, {
        **ARMS[args.arm], "init_weights": None, "base_lr_scale": 1.0,
        "epochs": args.epochs, "iterations_per_epoch": args.iterations, "learning_rate": 2e-4,
        "lr_schedule": "cosine", "val_data": str(args.data / "data" / "canon-840-test"),
        "val_limit": 4, "threads": args.threads, "checkpoint_minutes": 10, "tensorboard": False,
        "cache": True})
    history = run / "history.jsonl"
    done = history.exists() and len(history.read_text().splitlines()) >= args.epochs
    if not done:
        train(config, run, resume=has_checkpoint(run), progress=False)
    scores_path = args.output / f"{args.arm}.json"
    scores = json.loads(scores_path.read_text()) if scores_path.exists() else {}
    best = run / "best.safetensors"
    for dataset in DEV:
        if dataset in scores:
            continue
        out = args.output / "eval" / dataset / args.arm
        subprocess.run([sys.executable, "-m", "dualpixel", "-q", "eval", "--dataset",
                        f"../shared/data/{dataset}", "--checkpoint", str(best), "--no-niqe",
                        "--figures", "0", "-o", str(out)], check=True,
                       stdout=subprocess.DEVNULL)
        summary = json.loads((out / "summary.json").read_text())
        scores[dataset] = summary
        scores_path.write_text(json.dumps(scores, indent=1))
    if "held_out" not in scores:
        scores["held_out"] = held_out_psnr(best, family)
        scores_path.write_text(json.dumps(scores, indent=1))
    print(json.dumps({k: (v if k == "held_out" else "written") for k, v in scores.items()}))


if __name__ == "__main__":
    main()
