"""Seconds per training iteration of the light RDPD (the shipped model's recipe), in one run.

One iteration = forward, Eq. 16 loss, backward and an Adam step on 8 random 128x128 DP frames
(``synthetic_as_frames``: single frames, no ConvLSTM state). Cases:

- ``skip``: the first frame's zero state skips the recurrent convolution (what training runs);
- ``zero-state``: the same frames with an explicit all-zero state, so the recurrent convolution
  runs (the cost before the skip; the outputs are equal);
- ``log-loss``: ``skip`` with ``loss_reduction: log`` (per-patch loss in dB);
- ``ema``: ``skip`` plus the moving average of the weights after each step (``ema_decay``);
- ``conv2d-edge``: ``skip`` with the edge loss computed as before: both images convolved with
  the 2-D Sobel kernels (``conv2d``; same values), instead of the separable shifted sums on their
  difference that :class:`~dualpixel.training.EdgeLoss` uses;
- ``contiguous``: ``skip`` with the weights and activations in contiguous memory (the trainer
  keeps them channels-last, config ``channels_last``; this is ``--set channels_last=false``).

On CUDA, and on CPUs that compute bfloat16 natively (where ``dualpixel train`` uses both), two
more cases of ``skip``:

- ``bf16``: bfloat16 autocast (config ``amp``), channels-last weights as the trainer has them.

Prints each case and the ratios to ``zero-state``; compare figures only within one run.

    .venv/bin/python benchmarks/bench_training.py [--width 0.5] [--patch 128] [--threads 2]
    python benchmarks/bench_training.py --device cuda --width 1 --patch 512
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
import torch.nn.functional as F

from dualpixel.models import build_model
from dualpixel.training import DeblurLoss, EdgeLoss, sobel_kernels, weight_average
from dualpixel.training.trainer import fast_numerics


class Conv2dEdgeLoss(EdgeLoss):
    """Eq. 15 by 2-D convolution of output and target (the computation before the separable one)."""

    def forward(self, output: torch.Tensor, target: torch.Tensor, *, per_image: bool = False
                ) -> tuple[torch.Tensor, torch.Tensor]:
        images = output.shape[:-3].numel()
        planes = torch.stack([output, target]).reshape(-1, 1, *output.shape[-2:])
        loss_x = loss_y = output.new_zeros(())
        for size in self.sizes:
            kernels = torch.from_numpy(np.stack(sobel_kernels(size))).float()[:, None]
            grads = F.conv2d(planes, kernels.to(planes.device)).unflatten(0, (2, -1))
            squared = (grads[0] - grads[1]).square()  # (N * C, 2, h, w)
            if per_image:  # (N, 2, C * h * w)
                squared = squared.unflatten(0, (images, -1)).transpose(1, 2).flatten(2)
                loss_x = loss_x + squared[:, 0].mean(dim=1)
                loss_y = loss_y + squared[:, 1].mean(dim=1)
            else:
                loss_x = loss_x + squared[:, 0].mean()
                loss_y = loss_y + squared[:, 1].mean()
        return loss_x / len(self.sizes), loss_y / len(self.sizes)


def seconds_per_iteration(
    case: str, width: float, patch: int, iterations: int, device: torch.device
) -> float:
    torch.manual_seed(0)
    model = build_model("rdpd", width=width, lstm_dropout=0.0, residual=True).to(device)
    if case != "contiguous":  # as the trainer lays the weights out (config channels_last)
        model = model.to(memory_format=torch.channels_last)
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-4)
    average = weight_average(model, 0.999) if case == "ema" else None
    criterion = DeblurLoss(reduction="log" if case == "log-loss" else "mean").to(device)
    if case == "conv2d-edge":
        criterion.edge = Conv2dEdgeLoss(criterion.edge.sizes)
    frames = torch.rand(8, 1, model.shape.in_channels, patch, patch, device=device)
    target = torch.rand(8, 1, 3, patch, patch, device=device)
    state = None
    if case == "zero-state":
        assert model.lstm is not None
        zeros = torch.zeros(8, model.shape.bottleneck, patch // 16, patch // 16, device=device)
        state = (zeros, zeros.clone())
    cuda = device.type == "cuda"
    times = []
    for index in range(iterations + 2):  # two warm-up iterations
        started = time.perf_counter()
        with torch.autocast(device.type, dtype=torch.bfloat16, enabled=case.startswith("bf16")):
            prediction, _ = model(frames, state)
        loss, _ = criterion(prediction.float(), target)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        if average is not None:
            average.update_parameters(model)
        if cuda:
            torch.cuda.synchronize()
        if index >= 2:
            times.append(time.perf_counter() - started)
    return sorted(times)[len(times) // 2]  # median


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=float, default=0.5)
    parser.add_argument("--patch", type=int, default=128)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=20)
    parser.add_argument("--device", default="cpu",
                        help="cpu or cuda (bf16 on CUDA and native-bf16 CPUs)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    print(f"rdpd width {args.width}, 8 x {args.patch}x{args.patch} frames, {args.device}, "
          f"{args.threads} threads, median of {args.iterations} iterations")
    cases = ["zero-state", "skip", "contiguous", "log-loss", "ema", "conv2d-edge"]
    if fast_numerics(device):
        cases += ["bf16"]
    results = {}
    for case in cases:
        results[case] = seconds_per_iteration(case, args.width, args.patch, args.iterations,
                                              device)
    for case, seconds in results.items():
        print(f"{case:>10}: {seconds:.3f} s/iteration "
              f"({seconds / results['zero-state']:.2f} x zero-state)")


if __name__ == "__main__":
    main()
