"""Time one 1920x1080 frame per camera set: our renderer (exact and fast layering) against a
baseline that follows the authors' algorithm, in one run, and print the ratios and PSNRs.

Baseline (written by us after the paper and the authors' code): integer CoC layers from
2,000 depth bins up to 250 m, listed per camera as their generator does (17 layers for set0, 45
for set4, whether the frame holds them or not); each layer filters the *whole frame* with its
left, right and combined kernels through OpenCV's ``filter2D`` and is pasted with a hard mask (no
compositing).
Ours composites back to front with blurred masks and works only inside each layer's support;
``exact`` is the paper's fine layering (the reference), the default (``fast``) merges exact layers
where the blur is large and renders large blur at reduced resolution.
PSNR is fast against exact on the 8-bit scale, for left, right and combined.

``--end-to-end``: the whole ``dualpixel synth`` command on a 3-frame sequence
(``--no-noise --no-distortion``; start-up, reading, rendering and writing four PNGs and a defocus
map per frame) against as many frames of the baseline, per camera set, in one run (``--frames``
to amortise start-up over a longer sequence). With
``--authors-code DIR`` (a checkout of the authors' ``synthetic_dp_defocus_blur_code`` folder: their
generator script, ``generate_bw_kernel.py`` and ``set_N.npy``; not shipped here) their generator
itself also runs on the same frames, stored as SYNTHIA-SF RGB and encoded depth: it renders
the five camera sets one after another, each set's time is read from the line it prints when
it starts the set (their start-up is not counted), and it is stopped once the sets asked for
are timed. Their script imports ``wand`` (ImageMagick) for radial distortion, which is off;
without it installed a stand-in module that refuses to be used is put on their path.

    .venv/bin/python benchmarks/bench_synthesis.py [--device cuda] [--sets set0,set4]
    .venv/bin/python benchmarks/bench_synthesis.py --end-to-end --sets set0,set4 \
        [--frames 3] [--authors-code CHECKOUT/synthetic_dp_defocus_blur_code]

``--batched``: the batched renderer (:mod:`dualpixel.synthesis.batched_renderer`, many frames
at once) against exact for every set (PSNR L / R / C, beside the default's) at the given size,
and frames per second of the default (frame by frame) and the batched renderer (``--batch``
frames per call) for set0 at 840x560 and 1920x1080. ``--training``: training iterations per
second of rdpd-light (8 crops of 256 px) on a written dataset and on an on-the-fly source of
the same settings (:mod:`dualpixel.synthesis.on_the_fly`), CPU loader (``--loader-workers``).

    .venv/bin/python benchmarks/bench_synthesis.py --batched [--device cuda] [--batch 8]
    .venv/bin/python benchmarks/bench_synthesis.py --training [--loader-workers 0]

``--profile`` with ``--batched`` or ``--training``: where the time goes instead of the tables:
one batched call of set0 at the given size (``torch.profiler``: operators by host time and, on
CUDA, by device time; then the Python functions by cumulative time; then the operators it
dispatches on the frames, each a kernel launch on a GPU, and on the kernels, made on the CPU
whatever the device), or the training run of each
``--data`` source under ``cProfile`` (the training process only; loader workers are not seen).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from dualpixel.optics.psf import PSFParams, dp_psf
from dualpixel.optics.thin_lens import PAPER_LENS_SETS, coc_radius
from dualpixel.synthesis.renderer import quantise_layers, render_dp_views
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence


def authors_layers(camera) -> list[tuple[float, float, float]]:
    """The authors' layer list: (integer CoC, near, far) over 2,000 depth bins of 0-250 m.

    As in their generator, the list is precomputed per camera from the bins' centres (runs of
    equal rounded CoC merged) and does not depend on the frame: every layer is filtered, present
    or not.
    """
    edges = np.arange(2001) / 2000 * 250.0
    centres = torch.from_numpy(((edges[:-1] + edges[1:]) / 2).astype(np.float32))
    coc = np.rint(coc_radius(centres, camera).numpy())
    layers: list[list[float]] = []
    for value, near, far in zip(coc, edges[:-1], edges[1:]):
        if layers and layers[-1][0] == value:
            layers[-1][2] = far
        else:
            layers.append([float(value), float(near), float(far)])
    layers[-1][2] = np.inf  # depth clipped at 250 m falls in the last layer
    return [tuple(layer) for layer in layers]


def authors_algorithm(image: np.ndarray, depth: np.ndarray, camera, params: PSFParams):
    """Hard-masked whole-frame filtering per layer of :func:`authors_layers`, ``(H, W, 3)``."""
    views = [np.zeros_like(image) for _ in range(3)]
    for radius, near, far in authors_layers(camera):
        mask = (depth >= near) & (depth < far)
        kernels = dp_psf(radius, params)
        for view, kernel in zip(views, (2 * kernels.left, 2 * kernels.right, kernels.combined)):
            flipped = np.ascontiguousarray(kernel.numpy()[::-1, ::-1])  # filter2D correlates
            blurred = cv2.filter2D(image, -1, flipped, borderType=cv2.BORDER_CONSTANT)
            view[mask] = blurred[mask]
    return views


def psnr8(a: torch.Tensor, b: torch.Tensor) -> float:
    a8, b8 = (torch.round(x.clamp(0, 1) * 255) for x in (a, b))
    mse = float(((a8 - b8) ** 2).mean())
    return float("inf") if mse == 0 else 10 * np.log10(255**2 / mse)


def timed(fn, device: str):
    """(result, wall seconds, CPU seconds of the whole process: all threads)."""
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    start, cpu = time.perf_counter(), time.process_time()
    result = fn()
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    return result, time.perf_counter() - start, time.process_time() - cpu


def median_timed(fn, device: str, repeat: int):
    """(result, median wall seconds, median CPU seconds) of ``repeat`` runs."""
    runs = [timed(fn, device) for _ in range(repeat)]
    walls, cpus = sorted(r[1] for r in runs), sorted(r[2] for r in runs)
    return runs[0][0], walls[repeat // 2], cpus[repeat // 2]


AUTHORS_SCRIPT = "synthetic_dp_defocus_blur.py"
AUTHORS_SETS = ("set0", "set1", "set2", "set3", "set4")  # the order their script renders them


def _write_synthia_sequence(scenes: Path, folder: Path) -> None:
    """Our procedural sequence as SYNTHIA-SF: ``RGBLeft/*.png`` and depth encoded in 8-bit RGB
    (metres = 1000 * (R + 256 G + 65536 B) / (2**24 - 1)), which is what their script reads."""
    for sub in ("RGBLeft", "DepthLeft"):
        (folder / sub).mkdir(parents=True)
    for rgb_path in sorted((scenes / "seq_000" / "rgb").glob("*.png")):
        shutil.copy(rgb_path, folder / "RGBLeft" / rgb_path.name)
        depth = np.load(scenes / "seq_000" / "depth" / f"{rgb_path.stem}.npy").astype(np.float64)
        code = np.rint(np.clip(depth, 0, 1000) / 1000 * (2**24 - 1)).astype(np.int64)
        bgr = np.stack((code >> 16, (code >> 8) & 255, code & 255), axis=-1).astype(np.uint8)
        cv2.imwrite(str(folder / "DepthLeft" / rgb_path.name), bgr)


def authors_generator(code: Path, scenes: Path, work: Path,
                      sets: list[str] | None = None) -> dict[str, float]:
    """Run the authors' generator on the scene folder's sequence; seconds per camera set.

    It renders the five sets in :data:`AUTHORS_SETS` order; it is stopped once the last of
    ``sets`` (all five if None) is timed, that is when the next set starts."""
    last = max((AUTHORS_SETS.index(name) for name in sets or AUTHORS_SETS
                if name in AUTHORS_SETS), default=len(AUTHORS_SETS) - 1)
    if not (code / AUTHORS_SCRIPT).is_file():
        sys.exit(f"--authors-code {code}: no {AUTHORS_SCRIPT} there (give their "
                 "synthetic_dp_defocus_blur_code folder)")
    run = work / "authors"
    shutil.copytree(code, run)
    _write_synthia_sequence(scenes, work / "synthia" / "SEQ0")
    env = dict(os.environ)
    try:
        import wand.image  # noqa: F401
    except ImportError:  # only their radial distortion uses it, and it is off
        stub = work / "stub" / "wand"
        stub.mkdir(parents=True)
        (stub / "__init__.py").write_text("")
        (stub / "image.py").write_text(
            "class Image:\n    def __init__(self, *a, **k):\n"
            "        raise RuntimeError('ImageMagick (wand) is not installed')\n")
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(stub.parent),
                                                          env.get("PYTHONPATH")]))
    process = subprocess.Popen(
        [sys.executable, "-u", AUTHORS_SCRIPT, "--data_dir", f"{work / 'synthia'}/"],
        cwd=run, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    marks = []
    for _ in process.stdout:  # one line as each camera set's sequence starts
        marks.append(time.perf_counter())
        if len(marks) == last + 2:  # the set after the last one wanted has started
            process.kill()
            break
    _, errors = process.communicate()
    if len(marks) < last + 2:
        marks.append(time.perf_counter())
        if process.returncode or len(marks) != len(AUTHORS_SETS) + 1:
            sys.exit(f"the authors' generator failed (exit {process.returncode}):\n"
                     f"{errors[-2000:]}")
    return {name: marks[k + 1] - marks[k] for k, name in enumerate(AUTHORS_SETS[:last + 1])}


def end_to_end(sets: list[str], width: int, height: int, repeat: int,
               authors_code: Path | None = None, frames: int = 3) -> None:
    """The command against the baseline's computation (and the authors' generator, when given)
    for the same ``frames`` frames."""
    from dualpixel.io.images import read_rgb
    from dualpixel.synthesis.scenes import write_scene_folder

    command = [str(Path(sys.executable).with_name("dualpixel"))]
    if not Path(command[0]).is_file():
        command = [sys.executable, "-m", "dualpixel"]
    params = PSFParams(n=6, alpha=0.6, beta=0.2)
    with tempfile.TemporaryDirectory() as folder:
        scenes = Path(folder) / "scenes"
        config = SceneConfig(width=width, height=height, frames=frames, layout="photo")
        write_scene_folder(scenes, 1, config, seed=0, progress=False)
        first = scenes / "seq_000"
        rgb = read_rgb(first / "rgb" / "frame_0000.png")
        depth = np.load(first / "depth" / "frame_0000.npy")
        authors = {}
        if authors_code is not None:
            print(f"running the authors' generator on the {frames} frames (all five sets) ...",
                  flush=True)
            authors = authors_generator(authors_code, scenes, Path(folder), sets)
        print(f"{frames} frames {width}x{height}: `dualpixel synth` (the command, I/O and "
              f"start-up) against {frames} frames of the baseline's computation"
              + (" and the authors' generator (reading, rendering, writing)" if authors else ""))
        extra = " authors' generator s | command / authors' |" if authors else ""
        print(f"| set | command s | baseline s ({frames} frames) | command / baseline |{extra}")
        print("|---|---|---|---|" + ("---|---|" if authors else ""))
        for name in sets:
            walls = []
            for _ in range(repeat):
                out = Path(folder) / "out"
                shutil.rmtree(out, ignore_errors=True)
                started = time.perf_counter()
                subprocess.run([*command, "-q", "synth", "--input", str(scenes), "--output",
                                str(out), "--lens-sets", name, "--no-noise", "--no-distortion"],
                               check=True, capture_output=True)
                walls.append(time.perf_counter() - started)
            camera = PAPER_LENS_SETS[name]
            _, per_frame, _ = median_timed(
                lambda cam=camera: authors_algorithm(rgb, depth, cam, params), "cpu", 1)
            command_s, baseline_s = float(np.median(walls)), frames * per_frame
            theirs = (f" {authors[name]:.2f} | {command_s / authors[name]:.3f} |"
                      if name in authors else "")
            print(f"| {name} | {command_s:.2f} | {baseline_s:.2f} | "
                  f"{command_s / baseline_s:.3f} |{theirs}", flush=True)


def dead_leaves_frames(width: int, height: int, count: int, device: str
                       ) -> tuple[torch.Tensor, torch.Tensor]:
    """``count`` dead-leaves frames on ``device``: images ``(B, 3, H, W)`` and depths
    ``(B, H, W)``."""
    frames = [render_scene_sequence(k, SceneConfig(width=width, height=height, frames=1,
                                                   leaves=40))[0] for k in range(count)]
    images = torch.stack([torch.from_numpy(rgb).permute(2, 0, 1) for rgb, _ in frames])
    depths = torch.stack([torch.from_numpy(depth) for _, depth in frames])
    return images.to(device), depths.to(device)


def batched(sets: list[str], width: int, height: int, device: str, batch: int,
            repeat: int) -> None:
    """Accuracy of the batched renderer against exact per set, and frames per second."""
    from dualpixel.synthesis.batched_renderer import render_batch

    images, depths = dead_leaves_frames(width, height, batch, device)
    params = PSFParams(n=6, alpha=0.6, beta=0.2)
    print(f"frame {width}x{height} on {device}, torch threads {torch.get_num_threads()}")
    print("| set | PSNR default vs exact L / R / C (dB) | PSNR batched vs exact L / R / C (dB) |")
    print("|---|---|---|")
    for name in sets:
        coc = coc_radius(depths[0], PAPER_LENS_SETS[name])
        exact = render_dp_views(images[0], coc, params, mode="exact")
        fast = render_dp_views(images[0], coc, params)
        left, right = render_batch(images[:1], coc[None], params)
        mine = (left[0], right[0])
        cells = []
        for views in (fast, mine):
            cells.append(" / ".join(f"{v:.1f}" for v in (
                psnr8(exact[0], views[0]), psnr8(exact[1], views[1]),
                psnr8((exact[0] + exact[1]) / 2, (views[0] + views[1]) / 2))))
        print(f"| {name} | {cells[0]} | {cells[1]} |", flush=True)
    print(f"\n| set0 | default frames/s | batched frames/s ({batch} per call) | "
          "batched / default |")
    print("|---|---|---|---|")
    for w, h in ((840, 560), (1920, 1080)):
        scaled = torch.nn.functional.interpolate(images, size=(h, w), mode="bilinear")
        depth = torch.nn.functional.interpolate(depths[:, None], size=(h, w))[:, 0]
        coc = coc_radius(depth, PAPER_LENS_SETS["set0"])
        render_batch(scaled[:1, :, :64, :64], coc[:1, :64, :64], params)  # warm-up
        def one_by_one(scaled=scaled, coc=coc):
            return [render_dp_views(scaled[k], coc[k], params) for k in range(batch)]

        def together(scaled=scaled, coc=coc):
            return render_batch(scaled, coc, params)

        _, t_fast, _ = median_timed(one_by_one, device, repeat)
        _, t_batch, _ = median_timed(together, device, repeat)
        print(f"| {w}x{h} | {batch / t_fast:.2f} | {batch / t_batch:.2f} | "
              f"{t_fast / t_batch:.2f} |", flush=True)
        if device.startswith("cuda"):
            print(f"peak GPU memory {torch.cuda.max_memory_allocated() / 2**30:.2f} GiB")


def _functions(profiler, rows: int = 30) -> None:
    """The package's and torch's functions of a ``cProfile.Profile`` by cumulative time."""
    import io
    import pstats

    text = io.StringIO()
    stats = pstats.Stats(profiler, stream=text).sort_stats("cumulative")
    stats.print_stats("dualpixel|torch/nn/functional|numpy", rows)
    print(text.getvalue())


def operator_counts(fn) -> dict[str, int]:
    """Torch operators one call of ``fn`` dispatches: on the frames (each a kernel launch on an
    accelerator), of them the synchronisations (a value read back to the host), and on the CPU
    whatever the device (the kernels, made by ``layer_kernels`` and stacked by ``_padded``,
    and the tiles chosen by ``_reached_tiles``)."""
    import traceback

    from torch.utils._python_dispatch import TorchDispatchMode

    counts = {"frames": 0, "synchronisations": 0, "cpu": 0}
    on_cpu = {"layer_kernels", "_padded", "_reached_tiles"}

    class Count(TorchDispatchMode):
        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            if {frame.name for frame in traceback.extract_stack(limit=40)} & on_cpu:
                counts["cpu"] += 1
            else:
                counts["frames"] += 1
                counts["synchronisations"] += func is torch.ops.aten._local_scalar_dense.default
            return func(*args, **(kwargs or {}))

    with Count():
        fn()
    return counts


def profile_batched(width: int, height: int, device: str, batch: int) -> None:
    """Where one :func:`render_batch` call of ``batch`` set0 frames spends its time."""
    import cProfile

    from torch.profiler import ProfilerActivity

    from dualpixel.synthesis.batched_renderer import render_batch

    images, depths = dead_leaves_frames(width, height, batch, device)
    coc = coc_radius(depths, PAPER_LENS_SETS["set0"])
    params = PSFParams(n=6, alpha=0.6, beta=0.2)
    _, warm, _ = timed(lambda: render_batch(images, coc, params), device)  # allocator, kernels
    activities = [ProfilerActivity.CPU]
    if device.startswith("cuda"):
        activities.append(ProfilerActivity.CUDA)
    with torch.profiler.profile(activities=activities) as prof:
        _, seconds, _ = timed(lambda: render_batch(images, coc, params), device)
    print(f"render_batch, {batch} set0 frames of {width}x{height} on {device}: warm-up "
          f"{warm:.3f} s, under the profiler {seconds:.3f} s")
    table = prof.key_averages()
    print(table.table(sort_by="self_cpu_time_total", row_limit=20))
    if device.startswith("cuda"):
        print(table.table(sort_by="self_cuda_time_total", row_limit=20))
    profiler = cProfile.Profile()
    profiler.enable()
    _, seconds, _ = timed(lambda: render_batch(images, coc, params), device)
    profiler.disable()
    print(f"under cProfile {seconds:.3f} s")
    _functions(profiler)
    for frames in sorted({1, batch}):
        counts = operator_counts(lambda n=frames: render_batch(images[:n], coc[:n], params))
        print(f"operators of one call of {frames} frame(s): " + ", ".join(
            f"{value} {name}" for name, value in counts.items()))


def training(iterations: int, loader_workers: int, device: str,
             sources: tuple[str, ...] = ("written", "fly", "fly-device"),
             profile: bool = False, cache: bool = False) -> None:
    """Iterations per second of rdpd-light on written and on-the-fly data of one setting;
    ``cache``: each process keeps the scenes it decoded (training's ``cache``)."""
    from dualpixel.synthesis.dataset import SynthConfig, synthesize_dataset
    from dualpixel.synthesis.on_the_fly import write_on_the_fly
    from dualpixel.synthesis.scenes import write_scene_folder
    from dualpixel.training import load_config, train

    settings = SynthConfig(lens_sets=("dslr-840",), psf_bank="pixel4", bit_depth=8,
                           noise_model="poisson-gaussian", noise_sigmas=(0.006, 0.025), seed=0)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_scene_folder(root / "scenes", 8, SceneConfig(width=840, height=560, frames=1,
                                                           layout="photo"), progress=False)
        started = time.perf_counter()
        synthesize_dataset(root / "scenes", "rgbd", root / "written", settings, workers=2,
                           progress=False)
        writing = time.perf_counter() - started
        write_on_the_fly(root / "fly", root / "scenes", "rgbd", settings)
        print(f"rdpd-light, 8 crops of 256 px, {iterations} iterations on {device}, "
              f"{loader_workers} loader workers{', scenes kept decoded' if cache else ''}; "
              f"writing the 8 frames took {writing:.1f} s")
        print("| data | iterations/s |")
        print("|---|---|")
        labels = {"written": "written", "fly": "on the fly, rendered by the loader",
                  "fly-device": f"on the fly, rendered on {device} "
                                + ("by each loader process" if loader_workers else "in training")}
        for name, label in labels.items():
            if name not in sources:
                continue
            config = load_config(None, dict(
                model="rdpd", width=0.5, residual=True, refiner=[32, 64, 128],
                render_on="device" if name == "fly-device" else "loader",
                synthetic_data=str(root / name.removesuffix("-device")),
                synthetic_as_frames=True, patch_size=256, sequence_batch=4, sequence_frames=2,
                epochs=1, iterations_per_epoch=iterations, workers=loader_workers,
                device=device, tensorboard=False, learning_rate=1e-4, cache=cache))
            if profile:
                import cProfile

                profiler = cProfile.Profile()
                profiler.enable()
            result = train(config, root / f"run-{name}", progress=False)
            if profile:
                profiler.disable()
                print(f"{label}: the training process under cProfile")
                _functions(profiler)
            seconds = result.history[-1]["seconds"]
            print(f"| {label} | {iterations / seconds:.3f} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--sets", default="set0,set1,set2,set3,set4")
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--no-baseline", action="store_true", help="skip the slow baseline")
    parser.add_argument("--repeat", type=int, default=3,
                        help="runs of the default and the baseline; medians are printed")
    parser.add_argument("--end-to-end", action="store_true",
                        help="the synth command on a sequence against the baseline")
    parser.add_argument("--frames", type=int, default=3,
                        help="with --end-to-end: frames in the sequence (default 3)")
    parser.add_argument("--authors-code", type=Path, default=None,
                        help="with --end-to-end: the authors' synthetic_dp_defocus_blur_code "
                             "folder, to time their generator on the same frames")
    parser.add_argument("--batched", action="store_true",
                        help="the batched renderer: accuracy and frames per second")
    parser.add_argument("--batch", type=int, default=4, help="with --batched: frames per call")
    parser.add_argument("--training", action="store_true",
                        help="training iterations/s on written against on-the-fly data")
    parser.add_argument("--iterations", type=int, default=6, help="with --training")
    parser.add_argument("--loader-workers", type=int, default=0, help="with --training")
    parser.add_argument("--data", default="written,fly,fly-device",
                        help="with --training: which of written, fly (rendered by the loader) "
                             "and fly-device (rendered in training) to time")
    parser.add_argument("--profile", action="store_true",
                        help="with --batched or --training: where the time goes (see above)")
    parser.add_argument("--cache", action="store_true",
                        help="with --training: keep decoded scenes in memory (`cache`)")
    args = parser.parse_args()
    if args.batched and args.profile:
        profile_batched(args.width, args.height, args.device, args.batch)
        return
    if args.batched:
        batched(args.sets.split(","), args.width, args.height, args.device, args.batch,
                args.repeat)
        return
    if args.training:
        training(args.iterations, args.loader_workers, args.device,
                 tuple(args.data.split(",")), args.profile, args.cache)
        return
    if args.end_to_end:
        end_to_end(args.sets.split(","), args.width, args.height, args.repeat, args.authors_code,
                   args.frames)
        return

    rgb, depth = render_scene_sequence(0, SceneConfig(width=args.width, height=args.height,
                                                      frames=1, leaves=40))[0]
    image = torch.from_numpy(rgb).permute(2, 0, 1).to(args.device)
    params = PSFParams(n=6, alpha=0.6, beta=0.2)
    print(f"frame {args.width}x{args.height} on {args.device}, torch threads "
          f"{torch.get_num_threads()}")
    print("| set | layers baseline / exact / default | baseline s | exact s | default s | "
          "default / baseline, wall (CPU) | PSNR default vs exact L / R / C (dB) |")
    print("|---|---|---|---|---|---|---|")
    gpu_figures = []  # printed after the table
    for name in args.sets.split(","):
        camera = PAPER_LENS_SETS[name]
        coc = coc_radius(torch.from_numpy(depth).to(args.device), camera)
        layers = [len(authors_layers(camera))] + [
            quantise_layers(coc, 500, mode=m)[1].numel() for m in ("exact", "fast")]

        def render(mode: str, coc: torch.Tensor = coc):
            return render_dp_views(image, coc, params, mode=mode)

        # warm-up (thread pools, allocator) on a corner, for every method alike
        corner = (slice(0, 128), slice(0, 128))
        for mode in ("exact", "fast"):
            render_dp_views(image[:, corner[0], corner[1]], coc[corner], params, mode=mode)
        if not args.no_baseline:
            authors_algorithm(rgb[corner], depth[corner], camera, params)

        exact, t_exact, _ = timed(lambda: render("exact"), args.device)
        fast, t_fast, c_fast = median_timed(lambda: render("fast"), args.device, args.repeat)
        t_base = c_base = float("nan")
        if not args.no_baseline:
            _, t_base, c_base = median_timed(
                lambda cam=camera: authors_algorithm(rgb, depth, cam, params), "cpu", args.repeat)
        scores = [psnr8(exact[0], fast[0]), psnr8(exact[1], fast[1]),
                  psnr8((exact[0] + exact[1]) / 2, (fast[0] + fast[1]) / 2)]
        print(f"| {name} | {' / '.join(map(str, layers))} | {t_base:.2f} | {t_exact:.2f} | "
              f"{t_fast:.2f} | {t_fast / t_base:.3f} ({c_fast / c_base:.3f}) | "
              + " / ".join(f"{s:.1f}" for s in scores) + " |", flush=True)
        if args.device.startswith("cuda"):
            gpu_figures.append(f"{name} on {args.device}: default {1 / t_fast:.1f} frames/s, "
                               f"peak GPU memory so far "
                               f"{torch.cuda.max_memory_allocated() / 2**30:.2f} GiB")
    if gpu_figures:
        print("\n".join(gpu_figures))


if __name__ == "__main__":
    main()
