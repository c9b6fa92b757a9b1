"""Deblurring speed on one 1680x1120 DP frame, every case in one run, printed as ratios.

Default mode: the shipped default model (``--checkpoint``: another shipped name) on
the default path (``--precision auto``:
bf16 autocast and channels-last where the CPU computes bf16 natively) against ``--precision fp32``
(channels-last), against the same without :func:`~dualpixel.memory.reuse_freed_memory` (which
the ``dualpixel`` command calls at start-up; every other case has it), against the same without
:mod:`~dualpixel.inference.fusion` (convolutions and their activations run apart), against
the earlier path (fp32, contiguous memory, fresh pages) and against
``--backend onnxruntime`` (fp32; its one-off export, cached per checkpoint, timed apart and done
in a temporary cache folder; skipped without the ``onnx`` extra; on CUDA also ``--precision
fp16``, with frames per second and peak GPU memory); tiled at 512
against whole frames; the flips ensemble (4 members) against one plain pass; and the PSNR the
default precision gives against fp32 on the 7 Canon scenes at both resolutions.

``--paper``: the paper's full-width RDPD against DPDNet (the paper: 0.3 s against 0.5 s on a
GPU), tiled and two-scale RDPD.

Each case runs in its own process (its peak memory is its own), best of ``--repeats``. Those
minima move by 0.05-0.1 s from process to process, so the tiled / whole ratio is also measured
paired: both in one process, passes alternating, the median of the per-pair ratios.

    .venv/bin/python benchmarks/bench_inference.py [--device cuda] [--repeats N] [--paper]
    .venv/bin/python benchmarks/bench_inference.py [--device cuda] --profile default

``--profile CASE`` prints where one pass of that case spends its time instead. ``--command``:
the whole ``dualpixel deblur`` command (start-up, loading, reading, deblurring, writing) on one
1680x1120 pair of 8-bit PNGs, each run a fresh process, best of ``--repeats``, with its peak
memory (targets: 3.0 s and 2 GiB on 2 CPU cores), then where its time goes (imports, loading,
reading, the first pair's checks, the network, the output settings, writing; each run a fresh
process) and what the interpreter's start and exit add. ``--int8-convs``: one 3x3
convolution at the default network's sizes in fp32, bf16 and int8 (oneDNN's quantised
convolution), the lever for CPUs without AMX.
``--sequence N``: a temporal model (``--checkpoint``, e.g. ``rdpd-light-video``) on N
1680x1120 frames in a sequence, seconds per frame with its state carried (frames 2 to N run
the ConvLSTM's recurrent convolution) against its first frame (zero state), best of
``--repeats`` sequences; with ``--fuse-frames K`` each frame's views are first averaged with
up to K-1 earlier frames registered onto it (:mod:`dualpixel.inference.frame_fusion`), any
model.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def prepare(case: dict, device: str):
    """The case's :class:`~dualpixel.inference.Deblurrer`, its setup seconds and a random
    1680x1120 pair, after one warm-up pass."""
    import numpy as np
    import torch

    from dualpixel.inference import Deblurrer
    from dualpixel.inference.precision import Precision
    from dualpixel.memory import reuse_freed_memory
    from dualpixel.models import build_model, load_model
    from dualpixel.weights import resolve_checkpoint

    if not case.get("fresh_pages"):
        reuse_freed_memory()  # as the dualpixel command does at start-up
    torch.manual_seed(0)
    setup = time.perf_counter()
    if case["model"] == "shipped":
        model = load_model(resolve_checkpoint(case["checkpoint"]))
    else:
        model = build_model(case["model"])
    deblurrer = Deblurrer(model, device=device, tile=case.get("tile"),
                          precision=case.get("precision", "auto"), flips=case.get("flips", False),
                          multiscale=case.get("multiscale", False),
                          backend=case.get("backend", "torch"),
                          fuse_frames=case.get("fuse_frames", 1))
    setup = time.perf_counter() - setup
    if case.get("unfused") or case.get("legacy"):  # convolutions and activations apart
        deblurrer._net = deblurrer.model
    if case.get("legacy"):  # the earlier path: float32 in contiguous memory
        deblurrer.numerics = Precision("fp32", None, channels_last=False)
        deblurrer.model.to(memory_format=torch.contiguous_format)
    rng = np.random.default_rng(0)
    left = rng.random((1120, 1680, 3), dtype=np.float32)
    right = rng.random((1120, 1680, 3), dtype=np.float32)
    deblurrer(left, right)  # warm-up
    return deblurrer, setup, left, right


def timed_pass(deblurrer, left, right, device: str, *, reset: bool = True) -> float:
    """Seconds of one pass, from a reset state unless ``reset`` is False (a sequence's later
    frame); the GPU synchronised on both sides."""
    import torch

    if reset:
        deblurrer.reset()
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    started = time.perf_counter()
    deblurrer(left, right)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    return time.perf_counter() - started


def measure(case: dict, device: str, repeats: int) -> dict:
    """Seconds (best of ``repeats``, after a warm-up) and peak memory of one case."""
    import torch

    deblurrer, setup, left, right = prepare(case, device)
    times = [timed_pass(deblurrer, left, right, device) for _ in range(repeats)]
    result = {"seconds": min(times), "precision": deblurrer.numerics.name, "setup": setup,
              "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}
    if device.startswith("cuda"):
        result["peak_gpu_gib"] = torch.cuda.max_memory_allocated() / 2**30
    return result


def tile_pixels(height: int, width: int, tile: int) -> float:
    """Pixels the tiles of ``tile`` (default overlap) hold, over the frame's (padded) pixels."""
    from dualpixel.inference.deblur import default_overlap
    from dualpixel.inference.tiling import TileGrid
    from dualpixel.models.unet import SIZE_MULTIPLE

    grid = TileGrid(tile, default_overlap(tile))
    height, width = (-(-n // SIZE_MULTIPLE) * SIZE_MULTIPLE for n in (height, width))
    (span_h, tops), (span_w, lefts) = grid.layout(height), grid.layout(width)
    return span_h * len(tops) * span_w * len(lefts) / (height * width)


def measure_pair(first: dict, second: dict, device: str, repeats: int) -> dict:
    """``second`` against ``first`` in one process, passes alternating (after a warm-up of
    each): the median and range of the per-pair time ratios."""
    import statistics

    runs = [prepare(case, device) for case in (first, second)]
    ratios = []
    for _ in range(repeats):
        seconds = [timed_pass(deblurrer, left, right, device)
                   for deblurrer, _, left, right in runs]
        ratios.append(seconds[1] / seconds[0])
    return {"ratio": statistics.median(ratios), "low": min(ratios), "high": max(ratios)}


def profile(case: dict, device: str) -> None:
    """Print where one pass of ``case`` spends its time (``torch.profiler``, after a warm-up):
    the operators by their own host time and, on CUDA, by their own device time."""
    import torch
    from torch.profiler import ProfilerActivity

    deblurrer, _, left, right = prepare(case, device)
    activities = [ProfilerActivity.CPU]
    if device.startswith("cuda"):
        activities.append(ProfilerActivity.CUDA)
    deblurrer.reset()
    with torch.profiler.profile(activities=activities) as prof:
        started = time.perf_counter()
        deblurrer(left, right)
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        seconds = time.perf_counter() - started
    print(f"one pass, {deblurrer.numerics.name}, under the profiler: {seconds:.3f} s")
    table = prof.key_averages()
    print(table.table(sort_by="self_cpu_time_total", row_limit=15))
    if device.startswith("cuda"):
        print(table.table(sort_by="self_cuda_time_total", row_limit=15))


def canon_psnr_difference(device: str, checkpoint: str) -> dict[str, float]:
    """Mean PSNR (dB) of the default precision minus fp32, on the 7 Canon scenes per set."""
    from dualpixel.evaluation.metrics import psnr
    from dualpixel.inference import Deblurrer
    from dualpixel.io.images import read_rgb
    from dualpixel.models import load_model
    from dualpixel.weights import resolve_checkpoint

    model = load_model(resolve_checkpoint(checkpoint))
    default = Deblurrer(model, device=device)
    exact = Deblurrer(model, device=device, precision="fp32")
    differences = {}
    for name in ("canon-dp-real", "canon-dp-real-hd"):
        scenes = sorted((SHARED / name).glob("scene_*"))
        if not scenes:
            continue
        gaps = []
        for scene in scenes:
            left, right, target = (read_rgb(scene / f"{n}.png")
                                   for n in ("view0", "view1", "target"))
            gaps.append(psnr(default(left, right), target) - psnr(exact(left, right), target))
        differences[name] = (float(sum(gaps) / len(gaps)), max(abs(g) for g in gaps),
                             default.numerics.name)
    return differences


CASES = {
    "default": {"model": "shipped"},
    "fresh-pages": {"model": "shipped", "fresh_pages": True},
    "unfused": {"model": "shipped", "unfused": True},
    "fp32": {"model": "shipped", "precision": "fp32"},
    "legacy": {"model": "shipped", "precision": "fp32", "legacy": True, "fresh_pages": True},
    "onnxruntime": {"model": "shipped", "backend": "onnxruntime"},
    "tiled": {"model": "shipped", "tile": 512},
    "flips": {"model": "shipped", "flips": True},
}
FP16_CASE = {"model": "shipped", "precision": "fp16"}  # CUDA only
PAPER_CASES = {
    "rdpd": {"model": "rdpd", "precision": "fp32"},
    "dpdnet": {"model": "dpdnet", "precision": "fp32"},
    "rdpd-tiled": {"model": "rdpd", "precision": "fp32", "tile": 512},
    "rdpd-two-scales": {"model": "rdpd", "precision": "fp32", "multiscale": True},
}


def _command_pair(folder: Path) -> tuple[Path, Path]:
    """A photo-like 1680x1120 pair of 8-bit PNGs (smoothed noise) in ``folder``."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(0)
    views = []
    for side in ("left", "right"):
        image = cv2.GaussianBlur(rng.random((1120, 1680, 3), dtype=np.float32), (0, 0), 2)
        views.append(folder / f"{side}.png")
        cv2.imwrite(str(views[-1]), np.clip(image * 255, 0, 255).astype(np.uint8))
    return views[0], views[1]


def _command_arguments(views: tuple[Path, Path], output: Path, checkpoint: str,
                       device: str) -> list[str]:
    return ["-q", "deblur", "--left", str(views[0]), "--right", str(views[1]), "-o",
            str(output), "--checkpoint", checkpoint, "--device", device]


def command_time(checkpoint: str, device: str, repeats: int) -> tuple[float, float]:
    """Best wall seconds of the whole ``dualpixel deblur`` command on a 1680x1120 pair (photo-
    like: smoothed noise), each run a fresh process, and the largest peak RSS (GiB)."""
    executable = str(Path(sys.executable).with_name("dualpixel"))
    best, peak = float("inf"), 0.0
    with tempfile.TemporaryDirectory() as folder:
        views = _command_pair(Path(folder))
        for _ in range(repeats):
            command = [executable, *_command_arguments(views, Path(folder) / "out.png",
                                                       checkpoint, device)]
            started = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            best = min(best, time.perf_counter() - started)
            peak = max(peak, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20)
    return best, peak


#: The command's stages (:func:`command_stages`): the function each is timed around.
STAGES = {"reading": ("dualpixel.inference.jobs", "_read_pair"),
          "first pair's checks": ("dualpixel.inference.jobs", "_check_first_frame"),
          "network": ("dualpixel.inference.deblur", "Deblurrer.network_output"),
          "output settings (brightness tied)": ("dualpixel.inference.deblur", "Deblurrer.finish"),
          "writing": ("dualpixel.inference.jobs", "write_png")}


def stage_times(arguments: list[str]) -> dict[str, float]:
    """Seconds of each stage of one ``dualpixel`` command run in this (fresh) process:
    ``imports`` (the command line, then the inference modules, torch among them, which the
    command imports while its first pass's memory is faulted in beside them), ``loading``
    (from there to the first frame's reading: the inputs planned, the model built), then
    :data:`STAGES`, each the time inside its function."""
    import functools
    import importlib

    from dualpixel.memory import Prefault

    started = time.perf_counter()
    import dualpixel.cli.main

    def timed_stages() -> None:
        for stage, (module_name, attribute) in STAGES.items():
            owner = importlib.import_module(module_name)
            *classes, name = attribute.split(".")
            for class_name in classes:
                owner = getattr(owner, class_name)
            function = getattr(owner, name)

            @functools.wraps(function)
            def timed(*args, _function=function, _stage=stage, **kwargs):
                begun = time.perf_counter()
                seconds.setdefault("loading", begun - started - seconds["imports"])
                try:
                    return _function(*args, **kwargs)
                finally:
                    seconds[_stage] = seconds.get(_stage, 0.0) + time.perf_counter() - begun
            setattr(owner, name, timed)

    release = Prefault.release

    def imported(self) -> None:  # the command's imports end where it releases the memory
        release(self)
        if "imports" not in seconds:
            seconds["imports"] = time.perf_counter() - started
            timed_stages()

    seconds: dict[str, float] = {}
    Prefault.release = imported
    dualpixel.cli.main.cli.main(arguments, standalone_mode=False)
    seconds["total in the process"] = time.perf_counter() - started
    return seconds


def command_stages(checkpoint: str, device: str, repeats: int) -> dict[str, tuple[float, float]]:
    """The fastest and slowest seconds of each stage (:func:`stage_times`) over ``repeats``
    runs of the command, each a fresh process."""
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        arguments = _command_arguments(_command_pair(Path(folder)), Path(folder) / "out.png",
                                       checkpoint, device)
        for _ in range(repeats):
            result = subprocess.run([sys.executable, __file__, "--stages-of",
                                     json.dumps(arguments)], check=True, capture_output=True,
                                    text=True)
            runs.append(json.loads(result.stdout.strip().splitlines()[-1]))
    return {stage: (min(r[stage] for r in runs), max(r[stage] for r in runs))
            for stage in runs[0]}


#: The 3x3 convolutions :func:`int8_convolutions` times: (in, out channels, height, width).
CONV_SHAPES = ((16, 16, 1120, 1680), (32, 32, 560, 840), (64, 64, 280, 420),
               (128, 128, 140, 210))


def int8_convolutions(repeats: int) -> list[dict[str, float | str]]:
    """Milliseconds (best of ``repeats``) of one 3x3 convolution with its ReLU at each of
    :data:`CONV_SHAPES` on the CPU: float32 and bfloat16 (oneDNN, fused, as the default path
    runs them), int8 (oneDNN's quantised convolution, uint8 activations, per-channel int8
    weights; output in bfloat16 or uint8), and quantising the bfloat16 input to uint8 through
    PyTorch's quantised tensors."""
    return [_convolution_times(*shape, repeats) for shape in CONV_SHAPES]


def _convolution_times(cin: int, cout: int, height: int, width: int, repeats: int
                       ) -> dict[str, float | str]:
    import torch

    def best(function) -> float:
        function()
        times = []
        for _ in range(repeats):
            started = time.perf_counter()
            function()
            times.append(time.perf_counter() - started)
        return 1e3 * min(times)

    weight, bias = torch.randn(cout, cin, 3, 3) * 0.1, torch.randn(cout) * 0.1
    x = torch.rand(1, cin, height, width).contiguous(memory_format=torch.channels_last)
    x16, w16, b16 = x.bfloat16(), weight.bfloat16(), bias.bfloat16()
    scale, scales = 1 / 255, weight.abs().amax(dim=(1, 2, 3)) / 127
    qx = (x / scale).round().clamp(0, 255).to(torch.uint8).contiguous(
        memory_format=torch.channels_last)
    qw = (weight / scales[:, None, None, None]).round().clamp(-128, 127).to(torch.int8)
    packed = torch.ops.onednn.qconv_prepack(qw, scales, scale, 0, [1, 1], [1, 1], [1, 1], 1,
                                            [1, cin, height, width])
    zero = torch.zeros(cout, dtype=torch.int64)

    def fused(a, w, b):
        return torch.ops.mkldnn._convolution_pointwise(a, w, b, [1, 1], [1, 1], [1, 1], 1,
                                                       "relu", [None], "")

    def int8(dtype, output_scale):  # a float output takes scale 1 (oneDNN's rule)
        return torch.ops.onednn.qconv2d_pointwise(qx, scale, 0, packed, scales, zero, bias,
                                                  [1, 1], [1, 1], [1, 1], 1, output_scale, 0,
                                                  dtype, "relu", [], "")

    return {"shape": f"{cin}->{cout} at {width}x{height}",
            "fp32": best(lambda: fused(x, weight, bias)),
            "bf16": best(lambda: fused(x16, w16, b16)),
            "int8 -> bf16": best(lambda: int8(torch.bfloat16, 1.0)),
            "int8 -> uint8": best(lambda: int8(None, 0.05)),
            "quantise bf16 input": best(lambda: torch.quantize_per_tensor(
                x16.float(), scale, 0, torch.quint8).int_repr())}


def sequence_time(checkpoint: str, device: str, frames: int, repeats: int,
                  fuse_frames: int | None = None) -> dict:
    """Best seconds of a sequence's first frame and mean of its later frames (state carried),
    over ``repeats`` sequences of ``frames`` random 1680x1120 pairs, on the default path;
    ``fuse_frames`` None: the model's own (a preset's, e.g. ``rdpd-light-video``)."""
    from dualpixel.weights import run_settings

    fuse_frames = run_settings(checkpoint, fuse_frames=fuse_frames)["fuse_frames"]
    deblurrer, _, left, right = prepare({"model": "shipped", "checkpoint": checkpoint,
                                         "fuse_frames": fuse_frames}, device)
    first, later = [], []
    for _ in range(repeats):
        times = [timed_pass(deblurrer, left, right, device, reset=n == 0) for n in range(frames)]
        first.append(times[0])
        later.append(sum(times[1:]) / (frames - 1))
    return {"temporal": deblurrer.model.temporal, "fuse_frames": fuse_frames,
            "first": min(first), "later": min(later),
            "precision": deblurrer.numerics.name,
            "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def run_cases(cases: dict, device: str, repeats: int) -> dict:
    results = {}
    for name, case in cases.items():
        if case.get("backend") == "onnxruntime":
            from dualpixel.errors import ParameterError
            from dualpixel.inference.onnx_runtime import check_backend

            try:  # the same check, and message, as deblur --backend onnxruntime
                check_backend("onnxruntime")
            except ParameterError as error:
                print(f"{name:<16} skipped ({error})")
                continue
            if device != "cpu":
                print(f"{name:<16} skipped (runs on the CPU only)")
                continue
        command = [sys.executable, __file__, "--one", json.dumps(case), "--device", device,
                   "--repeats", str(repeats)]
        with tempfile.TemporaryDirectory() as cache:  # a fresh ONNX cache: the export is timed
            output = subprocess.run(command, check=True, capture_output=True, text=True,
                                    env={**os.environ, "DUALPIXEL_CACHE_DIR": cache}).stdout
        results[name] = r = json.loads(output.strip().splitlines()[-1])
        extra = (f", peak GPU {r['peak_gpu_gib']:.2f} GiB, {1 / r['seconds']:.1f} frames/s"
                 if "peak_gpu_gib" in r else "")
        if case.get("backend") == "onnxruntime":
            extra += f", export once {r['setup']:.1f} s"
        print(f"{name:<16} {r['precision']:<5} {r['seconds']:7.2f} s   "
              f"peak RSS {r['peak_rss_gib']:.2f} GiB{extra}", flush=True)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--checkpoint", default=None,
                        help="a shipped model's name (default: the package's default model)")
    parser.add_argument("--repeats", type=int,
                        help="best of this many passes per case (default: 5; 2 with --paper)")
    parser.add_argument("--paper", action="store_true", help="full-width RDPD against DPDNet")
    parser.add_argument("--profile", metavar="CASE",
                        help="instead: profile one pass of CASE (default, fp32, fp16, tiled, ...)")
    parser.add_argument("--command", action="store_true",
                        help="instead: the whole dualpixel deblur command on a 1680x1120 pair")
    parser.add_argument("--sequence", type=int, metavar="N",
                        help="instead: a temporal model on N frames in a sequence")
    parser.add_argument("--fuse-frames", type=int, default=None, metavar="K",
                        help="with --sequence: views averaged with up to K-1 earlier frames "
                             "(default: the model's own)")
    parser.add_argument("--int8-convs", action="store_true",
                        help="instead: one 3x3 convolution in fp32, bf16 and int8 (oneDNN) at "
                             "the default network's sizes, CPU")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # internal: run one case as JSON
    parser.add_argument("--stages-of", help=argparse.SUPPRESS)  # internal: one command's stages
    parser.add_argument("--pair", help=argparse.SUPPRESS)  # internal: two cases, alternating
    args = parser.parse_args()
    if args.repeats is None:  # single passes vary by ~0.1 s; the full-width ones take minutes
        args.repeats = 2 if args.paper else 5
    if args.repeats < 1:
        parser.error(f"--repeats must be at least 1, got {args.repeats}")
    if args.one:
        print(json.dumps(measure(json.loads(args.one), args.device, args.repeats)))
        return
    if args.stages_of:
        print(json.dumps(stage_times(json.loads(args.stages_of))))
        return
    if args.int8_convs:
        import warnings

        warnings.filterwarnings("ignore", message=".*quantize_per_tensor")  # deprecated API
        rows = int8_convolutions(args.repeats)
        print("| 3x3 convolution + ReLU, ms | " + " | ".join(list(rows[0])[1:]) + " |")
        print("|---|" + "---|" * (len(rows[0]) - 1))
        for row in rows:
            print(f"| {row['shape']} | " + " | ".join(f"{v:.1f}" for k, v in row.items()
                                                      if k != "shape") + " |")
        return
    if args.pair:
        first, second = json.loads(args.pair)
        print(json.dumps(measure_pair(first, second, args.device, args.repeats)))
        return
    from dualpixel.device import resolve_device
    from dualpixel.errors import InputFileError, ParameterError
    from dualpixel.weights import DEFAULT_CHECKPOINT, resolve_checkpoint

    try:
        args.device = str(resolve_device(args.device))
        checkpoint = args.checkpoint or DEFAULT_CHECKPOINT
        resolve_checkpoint(checkpoint)
    except (ParameterError, InputFileError) as error:
        parser.error(str(error))
    shipped = {name: {**case, "checkpoint": checkpoint}
               for name, case in {**CASES, "fp16": FP16_CASE}.items()}
    print(f"model: {checkpoint}")
    if args.command:
        seconds, peak = command_time(checkpoint, args.device, args.repeats)
        print(f"dualpixel deblur, one 1680x1120 pair, whole command: {seconds:.2f} s "
              f"(target <= 3.0 s), peak RSS {peak:.2f} GiB (target <= 2 GiB)")
        print(f"its stages, fastest-slowest of {args.repeats} fresh processes (s):")
        stages = command_stages(checkpoint, args.device, args.repeats)
        for stage, (low, high) in stages.items():
            print(f"  {stage}: {low:.2f}-{high:.2f}")
        print(f"  the interpreter's start and exit (the whole command less the fastest total): "
              f"{seconds - stages['total in the process'][0]:.2f}")
        return
    if args.sequence is not None:
        if args.sequence < 2:
            parser.error(f"--sequence must be at least 2 frames, got {args.sequence}")
        r = sequence_time(checkpoint, args.device, args.sequence, args.repeats,
                          args.fuse_frames)
        kind = "temporal" if r["temporal"] else "no state to carry"
        if r["fuse_frames"] > 1:
            kind += f", views fused with up to {r['fuse_frames'] - 1} earlier frames"
        print(f"{checkpoint} ({kind}), 1680x1120, {r['precision']}: first frame "
              f"{r['first']:.2f} s, frames 2-{args.sequence} {r['later']:.2f} s each (ratio "
              f"{r['later'] / r['first']:.2f}), peak RSS {r['peak_rss_gib']:.2f} GiB")
        return
    if args.profile:
        cases = {**shipped, **PAPER_CASES}
        if args.profile not in cases:
            parser.error(f"--profile: unknown case {args.profile!r} (cases: "
                         f"{', '.join(cases)})")
        profile(cases[args.profile], args.device)
        return
    if args.paper:
        r = run_cases(PAPER_CASES, args.device, args.repeats)
        print(f"ratio RDPD / DPDNet (whole frame, {args.device}): "
              f"{r['rdpd']['seconds'] / r['dpdnet']['seconds']:.2f} (paper, GPU: 0.60)")
        print(f"ratio RDPD two scales / one scale: "
              f"{r['rdpd-two-scales']['seconds'] / r['rdpd']['seconds']:.2f} (arithmetic: 1.25)")
        return
    cases = {name: case for name, case in shipped.items()  # fp16 runs on CUDA only
             if name != "fp16" or args.device.startswith("cuda")}
    r = run_cases(cases, args.device, args.repeats)
    seconds = {name: result["seconds"] for name, result in r.items()}
    print(f"ratio default / --precision fp32: {seconds['default'] / seconds['fp32']:.2f} "
          "(target <= 0.35)")
    print(f"ratio default / without reuse_freed_memory: "
          f"{seconds['default'] / seconds['fresh-pages']:.2f}")
    print(f"ratio default / without the conv + activation fusion: "
          f"{seconds['default'] / seconds['unfused']:.2f}")
    print(f"ratio default / fp32 before #36 (contiguous, fresh pages): "
          f"{seconds['default'] / seconds['legacy']:.2f}")
    print(f"default per 1680x1120 image: {seconds['default']:.2f} s (target <= 3 s, idle machine)")
    if "onnxruntime" in seconds:
        print(f"ratio onnxruntime / --precision fp32: "
              f"{seconds['onnxruntime'] / seconds['fp32']:.2f}")
    print(f"ratio tiled 512 / whole: {seconds['tiled'] / seconds['default']:.2f} (target <= 1.3)")
    pair = json.dumps([shipped["default"], shipped["tiled"]])
    command = [sys.executable, __file__, "--pair", pair,
               "--device", args.device, "--repeats", str(max(args.repeats, 7))]
    paired = json.loads(subprocess.run(command, check=True, capture_output=True,
                                       text=True).stdout.strip().splitlines()[-1])
    print(f"ratio tiled 512 / whole, paired in one process: {paired['ratio']:.2f} "
          f"(pairs {paired['low']:.2f}-{paired['high']:.2f}; target <= 1.3; the tiles hold "
          f"{tile_pixels(1120, 1680, 512):.2f}x the pixels)")
    print(f"ratio flips (4 members) / plain: "
          f"{seconds['flips'] / seconds['default']:.2f} (arithmetic: 4)")
    for name, (mean, worst, chosen) in canon_psnr_difference(args.device, checkpoint).items():
        print(f"PSNR {chosen} - fp32 on {name} (7 scenes): mean {mean:+.4f} dB, "
              f"worst scene {worst:.4f} dB (target <= 0.02)")


if __name__ == "__main__":
    main()
