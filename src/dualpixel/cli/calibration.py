"""``dualpixel pattern`` and ``dualpixel calibrate`` (supplement S1-S3)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from dualpixel.cli.common import CONTEXT, DPCommand, DPGroup, InputPath, OutputPath, parse_size
from dualpixel.names import PSF_BANK_NAMES


@click.command(cls=DPCommand, context_settings=CONTEXT)
@click.option("--kind", type=click.Choice(["disks", "squares"]), required=True,
              help="disks: PSF target (S1); squares: distortion target (S3).")
@click.option("--size", default="1920x1080", callback=parse_size, help="Display resolution WxH.")
@click.option("--spacing", type=click.IntRange(2), default=60,
              help="Distance between disk/square centres.")
@click.option("--radius-fraction", type=float, default=0.1,
              help="Disk radius as a fraction of the spacing (disks).")
@click.option("--square", type=int, default=None, help="Square side (squares; default spacing/2).")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True)
def pattern(kind: str, size: tuple[int, int], spacing: int, radius_fraction: float,
            square: int | None, output: Path) -> None:
    """Write a calibration target to show full-screen on a display."""
    from dualpixel.calibration.patterns import DiskGrid, disk_grid_pattern, square_grid_pattern
    from dualpixel.io.atomic import check_writable
    from dualpixel.io.images import check_image_path, write_png

    check_writable(check_image_path(output))
    width, height = size
    if kind == "disks":
        grid = DiskGrid(width, height, spacing, radius_fraction)
        image = disk_grid_pattern(grid)
        detail = f"{len(grid.centres())} disks of radius {grid.radius:g} px every {spacing} px"
    else:
        image = square_grid_pattern(width, height, square=square or spacing // 2, spacing=spacing)
        detail = f"squares of {square or spacing // 2} px every {spacing} px"
    write_png(output, image, bit_depth=8)
    click.echo(f"wrote {output} ({width}x{height}, {detail})")


@click.group(cls=DPGroup, context_settings=CONTEXT)
def calibrate() -> None:
    """Estimate DP PSFs, fit the PSF model and radial distortion (supplement S1-S3)."""


@calibrate.command("estimate-psf", context_settings=CONTEXT)
@click.option("--left", type=InputPath(dir_okay=False, path_type=Path), required=True,
              help="Left-view capture of the disk pattern.")
@click.option("--right", type=InputPath(dir_okay=False, path_type=Path), required=True)
@click.option("--combined", type=InputPath(dir_okay=False, path_type=Path), default=None,
              help="Combined capture (default: left + right).")
@click.option("--radius", type=float, required=True,
              help="Sharp disk radius in capture pixels (radius fraction x spacing in pixels).")
@click.option("--kernel-size", type=click.IntRange(3), default=61,
              help="Odd size of the estimated PSFs.")
@click.option("--lam", type=float, default=0.1, help="Weight of the l1 term.")
@click.option("--smoothness", type=float, default=0.1,
              help="Extra ||grad E||^2 weight (ours; 0 = the supplement's objective).")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True,
              help=".npz with left, right, combined (N, K, K) and centres.")
def estimate_psf(left: Path, right: Path, combined: Path | None, radius: float, kernel_size: int,
                 lam: float, smoothness: float, output: Path) -> None:
    """Non-blind PSF estimation per disk and view (S1)."""
    from dualpixel.calibration.psf_estimation import estimate_psfs, read_captures

    captures = read_captures(left, right, combined)
    click.echo("estimating the PSFs of every disk (about a minute on a CPU)...", err=True)
    estimate = estimate_psfs(captures, radius=radius,
                             kernel_size=kernel_size, lam=lam, smoothness=smoothness)
    estimate.save(output)
    click.echo(f"estimated {len(estimate.centres)} PSF(s) per view; wrote {output}")


@calibrate.command("fit-psf", context_settings=CONTEXT)
@click.option("--left", type=InputPath(dir_okay=False, path_type=Path), required=True,
              help="Measured left PSFs: .npy (N, S, S), or the .npz of estimate-psf.")
@click.option("--right", type=InputPath(dir_okay=False, path_type=Path), required=True)
@click.option("--output", "-o", "--report", "report",
              type=OutputPath(file_okay=False, path_type=Path), required=True,
              help="Folder for fits.csv, summary.json/.md and figure.png (--report: old name).")
@click.option("--limit", type=click.IntRange(1), default=None, help="Fit only the first N pairs.")
@click.option("--grid", type=click.Choice(["paper", "bank"]), default="paper",
              help="paper: the full S2 search; bank: only the 48-PSF bank's values (quick).")
@click.option("--camera", "camera_file", type=OutputPath(dir_okay=False, path_type=Path),
              default=None,
              help="Also write a camera file (for synth --camera) from the fits: the most "
                   "common shape, the fitted blur sizes.")
@click.option("--camera-name", default="measured", show_default=True, help="Its label.")
@click.option("--camera-width", type=click.IntRange(1), default=None,
              help="Width (px) of the frames the PSFs were measured in (required with "
                   "--camera).")
@click.option("--light", type=click.Choice(["linear", "encoded"]), default="linear",
              show_default=True,
              help="Where the camera's views are blurred: linear for PSFs measured on raw data.")
def fit_psf(left: Path, right: Path, report: Path, limit: int | None, grid: str,
            camera_file: Path | None, camera_name: str, camera_width: int | None,
            light: str) -> None:
    """Fit our PSF model and Punnappurath et al.'s to measured DP PSFs (S2)."""
    import time

    from dualpixel.calibration.measured_psfs import load_measured_psfs
    from dualpixel.calibration.psf_fit import (
        BANK_SEARCH_GRID,
        PAPER_SEARCH_GRID,
        fit_psf_models,
    )
    from dualpixel.calibration.report import write_fit_report
    from dualpixel.errors import InputFileError

    if camera_file is not None and camera_width is None:
        raise click.BadParameter("give the width of the measured frames with --camera",
                                 param_hint="--camera-width")
    lefts, rights = load_measured_psfs(left, "left"), load_measured_psfs(right, "right")
    if lefts.shape != rights.shape:
        raise InputFileError(right, f"shape {rights.shape} differs from {left.name} {lefts.shape}")
    lefts, rights = lefts[:limit], rights[:limit]
    started = time.perf_counter()
    fits = fit_psf_models(lefts, rights,
                          grid=PAPER_SEARCH_GRID if grid == "paper" else BANK_SEARCH_GRID)
    seconds = time.perf_counter() - started
    summary = write_fit_report(fits, {"left": lefts, "right": rights}, report,
                               meta={"seconds": round(seconds, 1), "grid": grid, "left": str(left),
                                     "right": str(right)})
    click.echo((report / "summary.md").read_text())
    click.echo(json.dumps(summary, indent=2))
    if camera_file is not None:
        from dualpixel.calibration.report import camera_from_fits

        camera_from_fits(fits, name=camera_name, width=camera_width, light=light).save(
            camera_file)
        click.echo(f"wrote {camera_file}")


@calibrate.command("fit-distortion", context_settings=CONTEXT)
@click.option("--capture", type=InputPath(dir_okay=False, path_type=Path), required=True,
              help="In-focus capture of the square pattern, centred and cropped to it.")
@click.option("--pattern", "pattern_path", type=InputPath(dir_okay=False, path_type=Path),
              required=True, help="The pattern image that was displayed.")
@click.option("--working-width", type=click.IntRange(16, 4096), default=480,
              help="Search resolution (width).")
def fit_distortion_command(capture: Path, pattern_path: Path, working_width: int) -> None:
    """Fit division-model coefficients c1, c2, c3 (S3)."""
    from dualpixel.calibration.distortion_fit import fit_distortion
    from dualpixel.io.images import read_rgb

    fit = fit_distortion(read_rgb(capture), read_rgb(pattern_path), working_width=working_width,
                         progress=True)
    c1, c2, c3 = fit.distortion.coefficients
    click.echo(json.dumps({"c1": c1, "c2": c2, "c3": c3, "correlation": fit.correlation,
                           "evaluations": fit.evaluations}))


@calibrate.command("camera", context_settings=CONTEXT)
@click.option("--input", "inputs", type=InputPath(file_okay=False, path_type=Path),
              required=True, multiple=True,
              help="Real DP pairs of one camera, with or without sharp targets: a DPDD-layout "
                   "folder or a folder of scene folders (view0/view1[/target].png); repeat for "
                   "more.")
@click.option("--split", default=None, help="Split of DPDD-layout folders [default: test].")
@click.option("--output", "-o", type=OutputPath(dir_okay=False, path_type=Path), required=True,
              help="camera.json to write (for `dualpixel synth --camera`).")
@click.option("--figure", type=OutputPath(dir_okay=False, path_type=Path), default=None,
              help="PNG: with targets, the fitted kernels beside the views and blur against "
                   "disparity per channel; without, each pair's blur map from its views.")
@click.option("--name", default=None, help="Label of the camera [default: the input's name].")
@click.option("--patch", type=click.IntRange(16), default=48, help="Block size in pixels.")
@click.option("--max-radius", type=click.FloatRange(1.0, 60.0), default=12.0,
              help="Largest CoC radius (px) searched; twice as large at twice the resolution.")
@click.option("--psf-grid", type=click.Choice(["single", *PSF_BANK_NAMES]), default="single",
              help="PSF shapes to choose from: single (the Pixel 4 fits' mode; quick) or a "
                   "bank's shapes (pixel4: 36, broad: 192; a few seconds per shape and pair).")
@click.option("--skip-misaligned", is_flag=True,
              help="Leave out (with a warning) pairs whose target is shifted against the views "
                   "by over 1 px, instead of stopping.")
@click.option("--falloff", is_flag=True,
              help="Also measure how the disparity ratio falls towards the frame's left and "
                   "right sides (with targets; the camera file's disparity_falloff).")
@click.option("--ignore-targets", is_flag=True,
              help="Calibrate from the two views alone even where targets exist (what a camera "
                   "without sharp captures gives); pairs without targets always are.")
def camera_command(inputs: tuple[Path, ...], split: str | None, output: Path,
                   figure: Path | None, name: str | None, patch: int, max_radius: float,
                   psf_grid: str, skip_misaligned: bool, falloff: bool,
                   ignore_targets: bool) -> None:
    """Measure a camera's DP blur model from real pairs: per-channel disparity ratio, PSF shape,
    where the blur happens (linear light or stored values), noise and blur sizes. With sharp
    targets the views are explained by the target blurred; without, by each other (the
    cross-convolution identity)."""
    import warnings

    from dualpixel.calibration.camera import DEFAULT_PSF, read_calibration_frames
    from dualpixel.errors import InputFileError
    from dualpixel.io.atomic import check_writable
    from dualpixel.optics.psf_bank import PSF_BANKS

    check_writable(output)
    if figure is not None:
        from dualpixel.viz.figures import check_figure_path

        check_writable(check_figure_path(figure))
    candidates = list(PSF_BANKS[psf_grid]) if psf_grid in PSF_BANKS else [DEFAULT_PSF]
    pairs = read_calibration_frames(inputs, split, require_target=False)
    with_target = [p for p in pairs if p[3] is not None]
    if with_target and len(with_target) < len(pairs) and not ignore_targets:
        missing = next(p[0] for p in pairs if p[3] is None)
        raise InputFileError(missing, "has no target where other pairs have one: give pairs "
                                      "all with targets or add --ignore-targets")
    from_views = ignore_targets or not with_target
    if falloff and from_views:
        raise click.UsageError("--falloff needs pairs with targets (the views alone fix the "
                               "product of disparity ratio and blur, not the ratio)")
    label = name or inputs[0].name
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if from_views:
            from dualpixel.calibration.target_free import (
                calibrate_camera_from_views,
                grey_as_one_channel,
            )

            click.echo(f"calibrating from the views alone ({len(pairs)} pairs"
                       f"{', targets unread' if with_target else ''})", err=True)
            pairs = [(n, *grey_as_one_channel(lv, rv), t) for n, lv, rv, t in pairs]
            calibration = calibrate_camera_from_views(
                [p[:3] for p in pairs], name=label, psf_candidates=candidates, patch=patch,
                max_radius=max_radius, progress=True)
        else:
            from dualpixel.calibration.camera import calibrate_camera

            calibration = calibrate_camera(pairs, name=label,
                                           psf_candidates=candidates, patch=patch,
                                           max_radius=max_radius,
                                           skip_misaligned=skip_misaligned, falloff=falloff,
                                           progress=True)
    for warning in caught:
        click.echo(f"Warning: {warning.message}", err=True)
    calibration.camera.save(output)
    click.echo(json.dumps(calibration.camera.to_dict(), indent=2))
    click.echo(f"light: {calibration.camera.light} (linear light explains "
               f"{100 * calibration.linear_share:.0f} % of the blocks better)")
    click.echo(f"wrote {output}")
    if figure is not None:
        if from_views:
            from dualpixel.calibration.camera_figure import render_views_figure

            click.echo(f"wrote {render_views_figure(calibration, pairs, figure)}")
        else:
            from dualpixel.calibration.camera_figure import render_camera_figure

            click.echo(f"wrote {render_camera_figure(calibration, figure)}")


COMMANDS = (pattern, calibrate)
