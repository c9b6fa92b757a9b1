"""The end-to-end demo: synthesise DP views, deblur them with the shipped model, report.

Default input: a short procedural "photo" sequence (``dualpixel.synthesis.scenes``) with a scene
seed never used for the shipped model's training data, synthesised with the ``dslr-840`` lens
set (a blur profile relative to the frame), and a real Canon DP photograph shipped with the
package (``demo_data/canon_scene_01``, MIT licence) shown beside the published DPDNet's
output. Alternatively a user's left/right pair (deblurred and shown; scored when a target is
given) or a user's RGB-D frame (synthesised with a lens set).
Writes ``index.html`` with the all-in-focus frame, depth and defocus maps, an animated GIF of the
DP views, input / output / target with zoomed crops, the PSFs used and a metrics table.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dualpixel.errors import ParameterError, check_seed
from dualpixel.evaluation.metrics import mae, psnr, ssim
from dualpixel.inference import Deblurrer, build_deblurrer, load_network
from dualpixel.io.atomic import atomic_path
from dualpixel.io.images import read_depth, read_rgb, write_png
from dualpixel.names import warn_renamed
from dualpixel.progress import progress_bar
from dualpixel.viz.comparison import render_comparison
from dualpixel.viz.html_report import Figure, Report, write_html_report
from dualpixel.viz.maps import render_colour_map, write_views_gif
from dualpixel.weights import DEFAULT_CHECKPOINT, resolve_checkpoint

__all__ = ["DemoFrame", "DemoResult", "run_demo"]

#: Scene seed of the default demo (training used seeds 0 and 1000: see MODEL_CARD.md).
DEMO_SEED = 2026

#: The real DP photograph shipped for the demo (see its README.md and LICENSE.md).
REAL_SCENE = "canon_scene_01"


def real_scene_dir() -> Path:
    """Folder of the shipped real Canon scene (view0/view1/input/target/dpdnet PNGs)."""
    from importlib import resources

    return Path(str(resources.files("dualpixel").joinpath("demo_data", REAL_SCENE)))


@dataclass
class DemoResult:
    report: Path
    metrics: dict
    seconds: float


@dataclass
class DemoFrame:
    """One frame of the demo, float32 ``(H, W, 3)`` images in [0, 1]; the scene (``rgb``,
    ``depth`` in metres, ``defocus`` in px) only for synthesised frames."""

    left: np.ndarray
    right: np.ndarray
    combined: np.ndarray
    target: np.ndarray | None = None
    output: np.ndarray | None = None
    rgb: np.ndarray | None = None
    depth: np.ndarray | None = None
    defocus: np.ndarray | None = None


def _synthetic_frames(rgbd: list[tuple[np.ndarray, np.ndarray]], lens_set: str, seed: int,
                      bar: tqdm, focus_distance: float | None = None):
    """The frames and the :class:`~dualpixel.synthesis.frame.SequenceDraw` they used."""
    from dualpixel.optics.psf_bank import PIXEL4_PSF_BANK
    from dualpixel.optics.thin_lens import DEFOCUS_PROFILES, focus_from_depth
    from dualpixel.synthesis.frame import draw_sequence, synthesize_frame

    lens = lens_set
    if lens_set in DEFOCUS_PROFILES:
        rng = np.random.default_rng(seed)
        focus = focus_distance or focus_from_depth(rgbd[0][1])
        lens = DEFOCUS_PROFILES[lens_set].lens(rng, focus, rgbd[0][1].shape[1])
    draw = draw_sequence(seed, lens, noise_sigmas=(0.01,), bank=PIXEL4_PSF_BANK,
                         noise_model="poisson-gaussian")
    frames = []
    for index, (rgb, depth) in enumerate(rgbd):
        frame = synthesize_frame(rgb, depth, draw, noise_seed=seed * 1000 + index)
        as_hwc = lambda t: t.permute(1, 2, 0).numpy()  # noqa: E731
        frames.append(DemoFrame(as_hwc(frame.left), as_hwc(frame.right), as_hwc(frame.combined),
                                target=as_hwc(frame.target), rgb=rgb, depth=depth,
                                defocus=frame.defocus.numpy()))
        bar.update()
    return frames, draw


def run_demo(
    output: str | Path,
    *,
    checkpoint: str = DEFAULT_CHECKPOINT,
    left: Path | None = None,
    right: Path | None = None,
    target: Path | None = None,
    rgb: Path | None = None,
    depth: Path | None = None,
    depth_scale: float = 0.001,
    frames: int = 3,
    size: tuple[int, int] = (840, 560),
    lens_set: str = "dslr-840",
    seed: int = DEMO_SEED,
    device: str = "cpu",
    tile: int | None = None,
    progress: bool = True,
    camera: str | None = None,
) -> DemoResult:
    """Run the demo and write ``output/index.html``; see the module docstring. ``lens_set``:
    what blurs a synthesised frame (``set0``..``set4`` or a profile such as ``dslr-840``);
    ``camera`` is its old name (until release 0.3)."""
    if camera is not None:
        warn_renamed("run_demo(camera=...)", "lens_set=...", stacklevel=2)
        lens_set = camera
    started = time.perf_counter()
    check_seed("seed", seed)
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    if (left is None) != (right is None) or (rgb is None) != (depth is None):
        raise ParameterError("give --left with --right, and --rgb with --depth")
    if left is not None and rgb is not None:
        raise ParameterError("give either a left/right pair or an RGB-D frame, not both")
    resolve_checkpoint(checkpoint)  # a bad name is refused before any work
    from dualpixel.device import resolve_device
    from dualpixel.io.atomic import check_writable

    device = str(resolve_device(device))
    check_writable(Path(output) / "index.html")  # before any work
    network = load_network(checkpoint, device=device)  # with the settings its weights run
    mode = "pair" if left is not None else "rgbd" if rgb is not None else "procedural"
    count = 1 if mode != "procedural" else frames
    # each frame made and deblurred, then the figures and the report
    bar = progress_bar(total=2 * count + 2, desc="demo", unit="step", enabled=progress)
    draw = None
    if mode == "pair":
        left_image, right_image = read_rgb(left), read_rgb(right)
        if left_image.shape != right_image.shape:
            raise ParameterError(f"{right}: size differs from {left}")
        sequence = [DemoFrame(left_image, right_image, (left_image + right_image) / 2,
                              target=read_rgb(target) if target is not None else None)]
        bar.update()
    else:
        focus = None
        if mode == "rgbd":
            rgbd = [(read_rgb(rgb), read_depth(depth, png_scale=depth_scale))]
        else:
            from dualpixel.synthesis.scenes import SceneConfig, render_scene

            config = SceneConfig(width=size[0], height=size[1], frames=frames, layout="photo")
            rgbd, focus = render_scene(seed, config)
        sequence, draw = _synthetic_frames(rgbd, lens_set, seed, bar, focus)

    deblurrer = build_deblurrer(network, tile=tile)  # as its weights run
    timings = []
    for index, frame in enumerate(sequence):
        tick = time.perf_counter()
        frame.output = deblurrer(frame.left, frame.right)
        timings.append(time.perf_counter() - tick)
        write_png(output / "frames" / f"output_{index:03d}.png", frame.output, bit_depth=8)
        bar.update()

    rows, metrics = [], {"frames": []}
    for index, frame in enumerate(sequence):
        if frame.target is None:
            continue
        entry = {"frame": index}
        for name, image in (("combined", frame.combined), ("output", frame.output)):
            entry[name] = {"psnr": psnr(image, frame.target), "ssim": ssim(image, frame.target),
                           "mae": mae(image, frame.target)}
        metrics["frames"].append(entry)
        rows.append([str(index), *_cells(entry)])
    if metrics["frames"]:
        mean = {n: {k: float(np.mean([f[n][k] for f in metrics["frames"]])) for k in
                    ("psnr", "ssim", "mae")} for n in ("combined", "output")}
        metrics["mean"] = mean
        rows.append(["mean", *_cells(mean)])

    figures = _figures(sequence, output, draw)
    if mode == "procedural":
        real_rows, metrics["real"], real_figure = _real_scene(deblurrer, output)
        rows += real_rows
        figures.insert(0, real_figure)
    bar.update()
    seconds = time.perf_counter() - started
    metrics.update({"mode": mode, "checkpoint": str(checkpoint), "seconds": seconds,
                    "deblur_seconds_per_frame": float(np.mean(timings)),
                    "synthesis": draw.describe() if draw is not None else {}})
    report = Report(
        title="dualpixel demo: DP synthesis and deblurring",
        intro=_intro(mode, checkpoint, draw, len(sequence), seconds, timings),
        tables=[("Metrics against the sharp target (input = combined DP image)",
                 ["frame", "input PSNR", "input SSIM", "input MAE", "output PSNR",
                  "output SSIM", "output MAE"], rows)] if rows else [],
        sections=figures,
        footer="Made by <code>dualpixel demo</code>. Metrics as in the paper's Table 1 "
               "(values in [0, 1]; SSIM over the colour image).",
    )
    with atomic_path(output / "metrics.json") as tmp:
        tmp.write_text(json.dumps(metrics, indent=2, default=float))
    path = write_html_report(report, output)
    bar.update()
    bar.close()
    return DemoResult(path, metrics, seconds)


def _real_scene(deblurrer: Deblurrer, output: Path) -> tuple[list[list[str]], dict, tuple]:
    """Deblur the shipped real Canon scene (with the demo's deblurrer, state reset); compare
    with DPDNet's published output."""
    folder = real_scene_dir()
    images = {name: read_rgb(folder / f"{name}.png") for name in
              ("view0", "view1", "input", "target", "dpdnet")}
    deblurrer.reset()  # another photograph: nothing carried over from the sequence
    ours = deblurrer(images["view0"], images["view1"])
    write_png(output / "frames" / "real_output.png", ours, bit_depth=8)
    target = images["target"]
    panels = {"input": images["input"], "ours": ours, "DPDNet (published)": images["dpdnet"],
              "target": target}
    scores = {name: f"{psnr(image, target):.2f} dB" for name, image in panels.items()
              if name != "target"}
    render_comparison(panels, output / "real_compare.png", title="real Canon DP photograph",
                      scores=scores, crop_by="ours")
    entry = {name: {"psnr": psnr(image, target), "ssim": ssim(image, target),
                    "mae": mae(image, target)}
             for name, image in (("combined", images["input"]), ("output", ours),
                                 ("dpdnet", images["dpdnet"]))}
    rows = [["real Canon scene (ours)", *_cells(entry)],
            ["real Canon scene (DPDNet)", *_cells({"combined": entry["combined"],
                                                   "output": entry["dpdnet"]})]]
    figure = ("A real DP photograph", [Figure(
        "real_compare.png", "Canon EOS 5D Mark IV, a scene never used in training (MIT licence, "
        "Abuolaim & Brown 2020): blurred input, our output, the published DPDNet's output "
        "(trained on real Canon photographs) and the all-in-focus target; bottom row zooms in "
        "where our output gains most over the input")],
        "Real photographs are the point of the paper: the model was trained on synthetic data "
        "only. DPDNet was trained on real pairs of this very camera (the DPDD), and its output "
        "was computed from the original views, while ours starts from this page's view, a "
        "dithered 8-bit GIF frame; so DPDNet leads here, as it does on the seven Canon scenes of "
        "the model card.")
    return rows, {"scene": REAL_SCENE, **entry}, figure


def _cells(scores: dict) -> list[str]:
    """Table cells: PSNR with 2 decimals, SSIM and MAE with 3, input then output."""
    return [f"{scores[n][k]:.{2 if k == 'psnr' else 3}f}"
            for n in ("combined", "output") for k in ("psnr", "ssim", "mae")]


def _intro(mode, checkpoint, draw, count, seconds, timings) -> str:
    source = {"procedural": f"a procedural RGB-D sequence of {count} frames (scene seed "
                            f"{DEMO_SEED}, never used in training)",
              "rgbd": "your RGB-D frame", "pair": "your left/right DP pair"}[mode]
    text = f"Input: {source}. Model: <code>{checkpoint}</code>. "
    if draw is not None:
        draw_info = draw.describe()
        cam, psf = draw_info["camera"], draw_info["psf"]
        distortion = draw_info["distortion"]["name"] if draw_info["distortion"] else "off"
        text += (f"Synthesis: lens set {cam['name']} (f = {cam['focal_length']:g} m, "
                 f"f/{cam['f_number']:g}, focused at {cam['focus_distance']:.2f} m), PSF n = "
                 f"{psf['n']}, "
                 f"alpha = {psf['alpha']}, beta = {psf['beta']}, kappa = {psf['kappa']}, "
                 f"distortion {distortion}, noise sigma {draw_info['noise_sigma']}. ")
    return text + (f"Deblurring took {np.mean(timings):.2f} s per frame; the whole demo "
                   f"{seconds:.1f} s.")


def _figures(sequence: list[DemoFrame], output: Path, draw) -> list:
    first = sequence[0]
    sections = []
    write_views_gif(first.left, first.right, output / "views.gif")
    sections.append(("Dual-pixel views", [Figure("views.gif", "Left and right DP views, "
                                                 "alternating: defocused regions shift between "
                                                 "them (DP disparity), in-focus ones do not.")],
                     ""))
    if first.rgb is not None:
        write_png(output / "all_in_focus.png", first.rgb, bit_depth=8)
        render_colour_map(first.depth, output / "depth.png", "depth (m)", cmap="viridis")
        render_colour_map(first.defocus, output / "defocus.png", "signed CoC radius (px)",
                          cmap="coolwarm", symmetric=True)
        sections.append(("Scene", [
            Figure("all_in_focus.png", "All-in-focus input frame"),
            Figure("depth.png", "Depth"),
            Figure("defocus.png", "Defocus map: signed circle-of-confusion radius (Eq. 1); "
                                  "blue in front of the focal plane, red behind"),
        ], ""))
    comparisons = []
    for index, frame in enumerate(sequence):
        panels = {"input": frame.combined, "output": frame.output}
        scores = {}
        has_target = frame.target is not None
        if has_target:
            panels["target"] = frame.target
            scores = {k: f"{psnr(panels[k], frame.target):.2f} dB" for k in ("input", "output")}
        name = f"compare_{index:03d}.png"
        render_comparison(panels, output / name, title=f"frame {index}", scores=scores,
                          crop_by="output" if has_target else None)
        comparisons.append(Figure(name, f"Frame {index}: blurred input, our output"
                                  + (", sharp target" if has_target else "")
                                  + "; bottom row zooms into the outlined crop ("
                                  + ("where our output gains most over the input"
                                     if has_target else "most detail") + ")"))
    sections.append(("Deblurring", comparisons, ""))
    if draw is not None:
        from dualpixel.viz.psf_figure import render_psf_figure

        coc = np.abs(np.concatenate([f.defocus.ravel() for f in sequence]))
        largest = max(2.0, float(np.percentile(coc, 99)))
        radii = sorted({round(-largest, 1), round(-largest / 3, 1), round(largest / 3, 1),
                        round(largest, 1)})
        render_psf_figure(output / "psfs.png", radii, draw.psf)
        sections.append(("PSFs used", [Figure("psfs.png", "DP PSFs of this sequence's shape "
                                              "parameters at radii within its defocus range "
                                              "(ours) beside Punnappurath et al.'s model")],
                         ""))
    return sections
