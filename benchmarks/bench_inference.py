"""Time RDPD and DPDNet (full width) on one 1680x1120 DP frame, in one run, and print the ratio.

The paper reports 0.3 s (RDPD) against 0.5 s (DPDNet) per image on a GPU. Each model runs in its
own subprocess so the peak resident memory it reports is its own; on CUDA the peak allocated GPU
memory is printed too. A tiled RDPD run (512-pixel tiles) shows the memory bound of tiling, and a
two-scale one (``--multiscale``: a second pass at half resolution) its cost.

    .venv/bin/python benchmarks/bench_inference.py [--device cuda] [--half] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time


def measure(model_name: str, device: str, repeats: int, tile: int | None, half: bool,
            multiscale: bool = False) -> dict:
    import numpy as np
    import torch

    from dualpixel.inference import Deblurrer
    from dualpixel.models import build_model

    torch.manual_seed(0)
    model = build_model(model_name)
    rng = np.random.default_rng(0)
    left = rng.random((1120, 1680, 3), dtype=np.float32)
    right = rng.random((1120, 1680, 3), dtype=np.float32)
    deblurrer = Deblurrer(model, device=device, tile=tile, half=half, multiscale=multiscale)
    deblurrer(left, right)  # warm-up
    times = []
    for _ in range(repeats):
        deblurrer.reset()
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        started = time.perf_counter()
        deblurrer(left, right)
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        times.append(time.perf_counter() - started)
    result = {"model": model_name, "tile": tile, "multiscale": multiscale, "seconds": min(times),
              "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}
    if device.startswith("cuda"):
        result["peak_gpu_gib"] = torch.cuda.max_memory_allocated() / 2**30
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--half", action="store_true", help="float16 autocast (CUDA)")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # internal: run one case as JSON
    args = parser.parse_args()
    if args.one:
        name, tile, scales = args.one.split(":")
        print(json.dumps(measure(name, args.device, args.repeats, int(tile) or None, args.half,
                                 multiscale=scales == "2")))
        return
    results = {}
    for case in ("rdpd:0:1", "dpdnet:0:1", "rdpd:512:1", "rdpd:0:2"):
        command = [sys.executable, __file__, "--one", case, "--device", args.device,
                   "--repeats", str(args.repeats)] + (["--half"] if args.half else [])
        output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
        results[case] = json.loads(output.strip().splitlines()[-1])
        r = results[case]
        extra = f", peak GPU {r['peak_gpu_gib']:.2f} GiB" if "peak_gpu_gib" in r else ""
        scales = "two scales" if r["multiscale"] else "one scale "
        print(f"{r['model']:<7} tile {r['tile'] or 'none':<5} {scales} {r['seconds']:7.2f} s   "
              f"peak RSS {r['peak_rss_gib']:.2f} GiB{extra}")
    ratio = results["rdpd:0:1"]["seconds"] / results["dpdnet:0:1"]["seconds"]
    print(f"ratio RDPD / DPDNet (whole 1680x1120 frame, {args.device}): {ratio:.2f} "
          f"(paper, GPU: 0.3 / 0.5 = 0.60)")
    ratio = results["rdpd:0:2"]["seconds"] / results["rdpd:0:1"]["seconds"]
    print(f"ratio RDPD two scales / one scale: {ratio:.2f} (the network's arithmetic: 1.25)")


if __name__ == "__main__":
    main()
