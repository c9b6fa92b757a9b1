"""``dualpixel psf``, ``scenes``, ``synth``, ``preview`` and ``stats``: PSFs and DP data."""

from __future__ import annotations

from pathlib import Path

import click

from dualpixel.cli.common import (
    CONTEXT,
    SEED,
    DPCommand,
    InputPath,
    OutputPath,
    float_list,
    parse_size,
)
from dualpixel.names import (
    ENCODINGS,
    LIGHT_SPACES,
    MAX_SEQUENCES,
    PSF_BANK_NAMES,
    PSF_MODELS,
    PSF_SHAPE_SOURCES,
    SCENE_LAYOUTS,
    SYNTH_SETTINGS_NAMES,
    SYNTH_SOURCES,
    warn_renamed,
)


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path),
              default=Path("psf_figure.png"), help="PNG figure to write.")
@click.option("--radii", default="-12,-6,-2,2,6,12", callback=float_list,
              help="Signed CoC radii in pixels (comma-separated).")
@click.option("--n", "order", type=float, default=3.0, help="Butterworth order n.")
@click.option("--alpha", type=float, default=0.4, help="Cutoff factor, D_o = alpha * 2|r|.")
@click.option("--beta", type=float, default=0.2, help="Minimum of the rescaled Butterworth term.")
@click.option("--kappa", type=float, default=0.14, help="Gaussian smoothing std per pixel of r.")
@click.option("--save", type=OutputPath(dir_okay=False, path_type=Path), default=None,
              help="Also store the kernels as .npz (left, right, combined, radii, ...).")
def psf(output: Path, radii: list[float], order: float, alpha: float, beta: float,
        kappa: float, save: Path | None) -> None:
    """Render DP PSFs of our model beside Punnappurath et al.'s (like the paper's Fig. 5)."""
    from dualpixel.io.atomic import check_writable
    from dualpixel.optics.psf import PSFParams
    from dualpixel.viz.figures import check_figure_path
    from dualpixel.viz.psf_figure import render_psf_figure, save_psf_kernels

    if not radii:
        raise click.BadParameter("give at least one radius", param_hint="--radii")
    check_writable(check_figure_path(output))
    if save is not None:
        check_writable(save)
    params = PSFParams(n=order, alpha=alpha, beta=beta, kappa=kappa)
    kernels = render_psf_figure(output, radii, params)
    click.echo(f"wrote {output}")
    if save is not None:
        click.echo(f"wrote {save_psf_kernels(save, kernels, radii, params)}")


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="RGB-D folder to write (one subfolder per sequence).")
@click.option("--sequences", type=click.IntRange(1, MAX_SEQUENCES), default=2,
              help="Number of sequences.")
@click.option("--frames", type=click.IntRange(1), default=4, help="Frames per sequence.")
@click.option("--size", default="320x240", callback=parse_size, help="Frame size WIDTHxHEIGHT.")
@click.option("--leaves", type=click.IntRange(0), default=28, help="Shapes per scene.")
@click.option("--seed", type=SEED, default=0, help="Scene seed.")
@click.option("--layout", type=click.Choice(SCENE_LAYOUTS), default=None,
              help="leaves: shapes at random depths; photo: an in-focus subject, ground plane, "
                   "background and occluders, with richer textures (writes the focus distance); "
                   "photographic: that layout on real photographs (--photos, else the package's "
                   "own few) [default: photographic with --photos, else leaves].")
@click.option("--photos", type=InputPath(path_type=Path), default=None,
              help="Folder of photographs for the photographic layout (JPEG, PNG, TIFF, ...; "
                   "never enlarged, so each needs a side of at least half the frame's shorter "
                   "side).")
@click.option("--skip-bad", is_flag=True,
              help="Leave out (and name) unreadable files of --photos instead of stopping.")
@click.option("--relief", type=click.FloatRange(0.0, 0.5), default=0.0, show_default=True,
              help="Relief of textured surfaces: the largest relative depth change their fine "
                   "structure makes (0: flat surfaces).")
@click.option("--workers", type=click.IntRange(1), default=1,
              help="Parallel processes (the output does not depend on it).")
def scenes(output: Path, sequences: int, frames: int, size: tuple[int, int], leaves: int,
           seed: int, layout: str | None, photos: Path | None, skip_bad: bool, relief: float,
           workers: int) -> None:
    """Render procedural RGB-D sequences (the built-in default input), or scenes whose surfaces
    are photographs (--photos)."""
    from dualpixel.synthesis.scenes import SceneConfig, photo_library, write_scene_folder

    if layout is None:
        layout = "photographic" if photos is not None else "leaves"
    if photos is not None and layout != "photographic":
        raise click.BadParameter(f"photographs are for --layout photographic, not {layout}",
                                 param_hint="--photos")
    if skip_bad and photos is None:
        raise click.BadParameter("is for --photos", param_hint="--skip-bad")
    config = SceneConfig(width=size[0], height=size[1], frames=frames, leaves=leaves,
                         layout=layout, relief=relief)
    library = photo_library(config, photos, skip_bad=skip_bad)
    write_scene_folder(output, sequences, config, seed=seed, workers=workers, photos=library)
    click.echo(f"wrote {sequences} sequences of {frames} frames to {output}"
               + (f" ({len(library)} photographs of {photos})" if photos is not None else ""))


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--input", "input_dir", type=InputPath(file_okay=False, path_type=Path),
              required=True, help="SYNTHIA-SF root or RGB-D folder.")
@click.option("--format", "fmt", type=click.Choice(["synthia", "rgbd"]), default="rgbd",
              help="Input layout.")
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path),
              required=True, help="Dataset folder (DPDD layout).")
@click.option("--settings", "settings_name", type=click.Choice(SYNTH_SETTINGS_NAMES),
              default="shipped", show_default=True,
              help="Where the options below start: what the shipped default model was trained "
                   "on (blur profiles dslr-840 and dslr-840-mild, the broad PSF bank, blur in "
                   "linear light, a real camera's Poisson-Gaussian noise 0.006-0.025), or the "
                   "paper's Sec. 3 (camera "
                   "sets set0..set4, its 48 PSF shapes, multiplicative noise 0.05-0.5).")
@click.option("--lens-sets", default=None,
              help="What blurs the frames: the paper's camera parameter sets set0..set4 (focal "
                   "length, aperture, focus distance) and/or blur profiles relative to the "
                   "frame (e.g. dslr-840), comma-separated; one output sequence per input and "
                   "lens set  [default: from --settings].")
@click.option("--cameras", "old_lens_sets", default=None, hidden=True,
              help="Old name of --lens-sets (until release 0.3).")
@click.option("--layers", type=click.IntRange(1), default=500, help="Maximum depth layers.")
@click.option("--render-mode", type=click.Choice(["fast", "exact"]), default="fast",
              show_default=True,
              help="fast: >= 45 dB from exact at a fraction of the time (benchmarks/"
                   "bench_synthesis.py); exact: every layer at full resolution (the reference).")
@click.option("--bit-depth", type=click.Choice(["8", "16"]), default="16", help="PNG bit depth.")
@click.option("--noise/--no-noise", default=True, help="Signal-dependent noise (Sec. 2.3).")
@click.option("--noise-model", type=click.Choice(["multiplicative", "poisson-gaussian"]),
              default=None, help="The paper's formula, or Foi et al.'s model  [default: from "
                                 "--settings].")
@click.option("--noise-sigmas", default=None, callback=float_list,
              help="Noise strengths to draw from, comma-separated  [default: from --settings].")
@click.option("--distortion/--no-distortion", default=True, help="Radial distortion (Eq. 5).")
@click.option("--psf-model", type=click.Choice(PSF_MODELS),
              default="ours", help="DP PSF model (the others for the paper's ablations).")
@click.option("--psf-bank", type=click.Choice(PSF_BANK_NAMES), default=None,
              help="PSF shapes to draw from: the paper's 48, around the real Pixel 4 fits, or "
                   "broad (fuller and smoother shapes too)  [default: from --settings].")
@click.option("--camera", "camera_file", default=None,
              help="A calibrated camera: a shipped one by name (canon-840, canon-840-linear, "
                   "canon-hd, canon-hd-linear, pixel4) or a file of `dualpixel calibrate "
                   "camera`: its PSF shape replaces --psf-bank (see --psf-shapes) and its "
                   "per-channel disparity ratio shapes the views.")
@click.option("--psf-shapes", type=click.Choice(PSF_SHAPE_SOURCES), default=None,
              help="With --camera: PSF shapes from the camera's fit, or drawn from --psf-bank "
                   "with the camera's disparity ratios and light  [default: camera].")
@click.option("--light", type=click.Choice(LIGHT_SPACES), default=None,
              help="Blur the stored (sRGB-encoded) values, as the paper's generator, or linear "
                   "light with the sRGB curve after, as a lens does  [default: the --camera "
                   "file's, else from --settings].")
@click.option("--grey", is_flag=True,
              help="Store every image as its green channel alone, as a phone's DP data are "
                   "(the Google Pixel's DP views are one green channel of the raw frame).")
@click.option("--encoding", type=click.Choice(ENCODINGS), default="srgb", show_default=True,
              help="How the images store light: display values (sRGB, as photographs), or "
                   "linear raw values above a black level, as a phone's DP data (needs linear "
                   "light: --light linear or a camera file that blurs in it).")
@click.option("--black-level", type=float, default=None,
              help="--encoding linear: the stored value of no light, a fraction of full "
                   "scale (e.g. 0.0625, 64 of 1023)  [default: 0].")
@click.option("--raw-gains", default=None, callback=float_list, metavar="LOW,HIGH",
              help="--encoding linear: exposure gains to draw per sequence, so that highlights "
                   "sit below the white level  [default: 1,1].")
@click.option("--view-coding", default=None, metavar="CODEC[:SHARE]",
              help="Code the two views of a share of the frames lossily, as real views often "
                   "reach a model: h264 (the pair as one H.264 animation, as DPDD's published "
                   "videos; needs PyAV) or jpeg, e.g. h264:0.5 (8-bit display-encoded views; "
                   "share 0.5 if not given).")
@click.option("--base-blur", default=None, callback=float_list, metavar="LOW,HIGH",
              help="Blur both views, not the target, by a Gaussian of std drawn per sequence "
                   "from LOW-HIGH px: the in-focus optics, which the thin lens leaves sharp "
                   "(real Canon views at 1620 px: about 0.6)  [default: 0,0].")
@click.option("--split", default="train", help="Split name for RGB-D input (SYNTHIA: SEQ3=test).")
@click.option("--max-depth", type=float, default=250.0, help="Clip depth here (metres).")
@click.option("--depth-scale", type=float, default=0.001,
              help="Metres per unit of 16-bit depth PNGs.")
@click.option("--seed", type=SEED, default=0, help="Seed of PSF shapes, noise and its draws.")
@click.option("--device", default="auto", help="auto, cpu, cuda, cuda:1, ...")
@click.option("--workers", type=click.IntRange(1), default=1, help="Parallel processes.")
@click.option("--png-compression", type=click.IntRange(0, 9), default=None,
              help="zlib level of all the PNGs: 0 (stored, fastest, 20-30 % larger) to 9 "
                   "(smallest, ~10x slower to write)  [default: the views stored, the target "
                   "with a fast run-length strategy].")
@click.option("--source", type=click.Choice(SYNTH_SOURCES), default="written", show_default=True,
              help="written: render every frame into the folder; on-the-fly: write only these "
                   "settings (on-the-fly.json), and training renders each crop as it draws it, "
                   "with a draw of its own (validation needs written frames).")
@click.option("--shard", default=None, callback=lambda _c, p, v: _shard(p, v), metavar="K/N",
              help="Render only the K-th of N interleaved parts of the frames (0-based), e.g. "
                   "K=$SLURM_ARRAY_TASK_ID; join the N folders with `dualpixel merge-shards`.")
def synth(input_dir: Path, fmt: str, output: Path, settings_name: str, lens_sets: str | None,
          old_lens_sets: str | None, layers: int, render_mode: str,
          bit_depth: str,
          noise: bool, noise_model: str | None, noise_sigmas: list[float] | None,
          distortion: bool, psf_model: str, psf_bank: str | None, camera_file: str | None,
          psf_shapes: str | None,
          light: str | None, grey: bool, encoding: str, black_level: float | None,
          raw_gains: list[float] | None, view_coding: str | None,
          base_blur: list[float] | None, split: str,
          max_depth: float,
          depth_scale: float, seed: int, device: str, workers: int,
          png_compression: int | None, source: str, shard: tuple[int, int] | None) -> None:
    """Synthesise DP views from RGB + depth into a DPDD-layout dataset (resumable)."""
    from dualpixel.optics.camera import load_camera
    from dualpixel.synthesis.dataset import SynthConfig, synthesis_settings, synthesize_dataset
    from dualpixel.synthesis.view_coding import ViewCoding

    settings = synthesis_settings(settings_name, camera=camera_file is not None)
    if old_lens_sets is not None:
        if lens_sets is not None:
            raise click.BadParameter("give --lens-sets only (--cameras is its old name)",
                                     param_hint="--cameras")
        warn_renamed("--cameras", "--lens-sets")
        lens_sets = old_lens_sets
    if lens_sets is not None:
        settings["lens_sets"] = tuple(c.strip() for c in lens_sets.split(",") if c.strip())
    for key, value in (("psf_bank", psf_bank), ("noise_model", noise_model),
                       ("noise_sigmas", tuple(noise_sigmas) if noise_sigmas else None),
                       ("light", light)):
        if value is not None:
            settings[key] = value
    config = SynthConfig(
        **settings,
        psf_model=psf_model, max_layers=layers, render_mode=render_mode,
        bit_depth=int(bit_depth),
        noise=noise, distortion=distortion, seed=seed,
        max_depth=max_depth, depth_scale=depth_scale, split=split,
        camera=None if camera_file is None else load_camera(camera_file).to_dict(),
        psf_shapes=psf_shapes, grey=grey, encoding=encoding,
        black_level=0.0 if black_level is None else black_level,
        raw_gains=(1.0, 1.0) if raw_gains is None else tuple(raw_gains),
        view_coding=None if view_coding is None
        else ViewCoding.parse(view_coding).require().as_dict(),
        base_blur=(0.0, 0.0) if base_blur is None else tuple(base_blur),
    )
    if source == "on-the-fly":
        from dualpixel.synthesis.on_the_fly import write_on_the_fly

        if shard is not None:
            raise click.BadParameter("an on-the-fly source has no frames to share out",
                                     param_hint="--shard")
        click.echo(f"wrote {write_on_the_fly(output, input_dir, fmt, config)} (frames are "
                   "rendered as training draws them)")
        return
    summary = synthesize_dataset(input_dir, fmt, output, config, workers=workers, device=device,
                                 shard=shard, png_compression=png_compression)
    click.echo(f"{summary['status']}: {summary['frames_done']}/{summary['frames_total']} frames "
               f"in {output}")


def _shard(param, value: str | None) -> tuple[int, int] | None:
    if value is None:
        return None
    try:
        index, count = (int(v) for v in value.split("/"))
    except ValueError:
        raise click.BadParameter(f"expected K/N, e.g. 0/4, got {value!r}", param=param) from None
    if count < 1 or not 0 <= index < count:
        raise click.BadParameter(f"need 0 <= K < N, got {value!r}", param=param)
    return index, count


@click.command("merge-shards", cls=DPCommand, context_settings=CONTEXT)
@click.argument("shards", nargs=-1, required=True,
                type=InputPath(file_okay=False, exists=True, path_type=Path))
@click.option("--output", "-o", type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="New dataset folder (or this merge's, cut short: it is finished): the "
                   "same files as one `synth` run without --shard.")
def merge_shards_command(shards: tuple[Path, ...], output: Path) -> None:
    """Join the folders of `synth --shard K/N` (all N of them) into one dataset."""
    from dualpixel.synthesis.dataset import merge_shards

    summary = merge_shards(list(shards), output)
    click.echo(f"merged {len(shards)} shards: {summary['frames_done']} frames in {output}")


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--input", "--dataset", "dataset",
              type=InputPath(file_okay=False, path_type=Path), required=True,
              help="Dataset folder written by `dualpixel synth`.")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path),
              default=Path("preview.png"), help="PNG contact sheet to write.")
@click.option("--rows", type=click.IntRange(1), default=5, help="Sequences to show.")
def preview(dataset: Path, output: Path, rows: int) -> None:
    """Show a synthetic dataset: target, left, right, combined and defocus per sequence."""
    from dualpixel.io.atomic import check_writable
    from dualpixel.viz.dataset_preview import render_dataset_preview
    from dualpixel.viz.figures import check_figure_path

    check_writable(check_figure_path(output))

    click.echo(f"wrote {render_dataset_preview(dataset, output, rows=rows)}")


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.argument("datasets", nargs=-1, required=True,
                type=InputPath(file_okay=False, path_type=Path))
@click.option("--split", default=None,
              help="Split of DPDD-layout folders [default: test, else train]; scene folders "
                   "(scene/view0.png ...) need none.")
@click.option("--limit", type=click.IntRange(1), default=None,
              help="At most this many frames per dataset, spread evenly over its sequences.")
@click.option("--patch", type=click.IntRange(16), default=64, help="Block size in pixels.")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), default=None,
              help="Histogram figure (PNG) of all datasets side by side.")
@click.option("--json", "json_path", type=OutputPath(dir_okay=False, path_type=Path),
              default=None, help="Write the percentiles as JSON too.")
@click.option("--disparity-ratio", "max_radius", type=click.FloatRange(1.0, 60.0), default=None,
              metavar="MAX_RADIUS",
              help="Also measure, on frames with targets, the disparity kept per colour channel "
                   "at a given blur (as `calibrate camera`: 1 = the paper's model), searching "
                   "CoC radii up to MAX_RADIUS px.")
def stats(datasets: tuple[Path, ...], split: str | None, limit: int | None, patch: int,
          output: Path | None, json_path: Path | None, max_radius: float | None) -> None:
    """Measure DP datasets: disparity, blur, noise and gradient content (percentiles).

    Give two datasets to compare them, e.g. synthetic training data beside real photographs.
    """
    from dualpixel.data.statistics import dataset_statistics, write_summary
    from dualpixel.io.atomic import check_writable
    from dualpixel.viz.figures import check_figure_path

    if output is not None:  # refuse a bad output before measuring
        check_writable(check_figure_path(output))
    if json_path is not None:
        check_writable(json_path)
    measured = [dataset_statistics(d, split=split, limit=limit, patch=patch, progress=True)
                for d in datasets]
    rows = [("frames", lambda s: str(s["frames"])), ("size", lambda s: s["size"])]
    for key, label in (("abs_disparity_px", "|disparity| px"), ("blur_sigma_px", "blur std px"),
                       ("noise_std", "noise std"), ("gradient_fraction", "gradient frac.")):
        for p in ("p25", "p50", "p75", "p90"):
            rows.append((f"{label} {p}", lambda s, k=key, p=p: "-" if s[k] is None else
                         f"{s[k][p]:.4g}"))
    if max_radius is not None:
        from dualpixel.calibration.camera import calibrate_camera, read_calibration_frames

        for dataset, stats_ in zip(datasets, measured):
            frames = read_calibration_frames([dataset], split)[:limit]
            camera = calibrate_camera(frames, patch=patch, max_radius=max_radius,
                                      skip_misaligned=True).camera
            stats_.extra["disparity_ratio"] = list(camera.disparity_ratio)
            stats_.extra["coc_percentiles"] = camera.coc_percentiles
        rows.append(("disparity ratio R/G/B", lambda s: "/".join(
            f"{v:.2f}" for v in s.get("disparity_ratio", [])) or "-"))
        rows.append(("CoC px p50 (p90)", lambda s: "-" if "coc_percentiles" not in s else
                     f"{s['coc_percentiles']['p50']:g} ({s['coc_percentiles']['p90']:g})"))
    summaries = [m.summary() for m in measured]
    click.echo(f"{'':<22}" + "".join(f"{s['name'][:20]:>22}" for s in summaries))
    for label, value in rows:
        click.echo(f"{label:<22}" + "".join(f"{value(s):>22}" for s in summaries))
    if json_path is not None:
        click.echo(f"wrote {write_summary(measured, json_path)}")
    if output is not None:
        from dualpixel.viz.statistics_figure import render_statistics_figure

        click.echo(f"wrote {render_statistics_figure(measured, output)}")


COMMANDS = (psf, scenes, synth, merge_shards_command, preview, stats)
