"""Entry point of the ``dualpixel`` command (click). Each command parses, converts and calls the
library once; the work lives in the library so a notebook user can call it directly."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from dualpixel import __version__
from dualpixel.errors import DualPixelError

CONTEXT = {"help_option_names": ["-h", "--help"], "show_default": True}


class _Group(click.Group):
    """Turns the library's own errors into a one-line message and exit status 2."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except DualPixelError as error:
            raise click.UsageError(str(error), ctx) from error


@click.group(cls=_Group, context_settings=CONTEXT)
@click.version_option(__version__, prog_name="dualpixel")
def cli() -> None:
    """dualpixel: dual-pixel defocus deblurring (Abuolaim et al., ICCV 2021)."""


def _float_list(_ctx, _param, value: str) -> list[float]:
    try:
        return [float(v) for v in value.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None


@cli.command(context_settings=CONTEXT)
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              default=Path("psf_figure.png"), help="PNG figure to write.")
@click.option("--radii", default="-12,-6,-2,2,6,12", callback=_float_list,
              help="Signed CoC radii in pixels (comma-separated).")
@click.option("--n", "order", type=float, default=3.0, help="Butterworth order n.")
@click.option("--alpha", type=float, default=0.4, help="Cutoff factor, D_o = alpha * 2|r|.")
@click.option("--beta", type=float, default=0.2, help="Minimum of the rescaled Butterworth term.")
@click.option("--kappa", type=float, default=0.14, help="Gaussian smoothing std per pixel of r.")
@click.option("--save", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also store the kernels as .npz (left, right, combined, radii, ...).")
def psf(output: Path, radii: list[float], order: float, alpha: float, beta: float,
        kappa: float, save: Path | None) -> None:
    """Render DP PSFs of our model beside Punnappurath et al.'s (like the paper's Fig. 5)."""
    from dualpixel.io.atomic import atomic_path
    from dualpixel.optics.psf import PSFParams
    from dualpixel.viz.psf_figure import render_psf_figure

    if not radii:
        raise click.BadParameter("give at least one radius", param_hint="--radii")
    params = PSFParams(n=order, alpha=alpha, beta=beta, kappa=kappa)
    kernels = render_psf_figure(output, radii, params)
    click.echo(f"wrote {output}")
    if save is not None:
        ours, theirs = kernels["ours"].numpy(), kernels["punnappurath"].numpy()
        with atomic_path(save) as tmp:
            with open(tmp, "wb") as handle:
                np.savez(
                    handle, left=ours[0], right=ours[1], combined=ours[2],
                    radii=np.asarray(radii), punnappurath_left=theirs[0],
                    punnappurath_right=theirs[1], punnappurath_combined=theirs[2],
                    params=np.asarray([order, alpha, beta, kappa]),
                )
        click.echo(f"wrote {save}")


if __name__ == "__main__":  # pragma: no cover
    cli()
