"""Entry point of the ``dualpixel`` command (click): the group, assembled from the command
modules. Each command parses, converts and calls the library once; the work lives in the
library so a notebook user can call it directly. Errors: see :mod:`dualpixel.cli.common`."""

from __future__ import annotations

import atexit
import gc
import os
import sys
import threading

import click

from dualpixel import __version__
from dualpixel.cli import adaptation, calibration, demo, inference, reproduce, synthesis, training
from dualpixel.cli.common import CONTEXT, DPGroup
from dualpixel.memory import reuse_freed_memory

__all__ = ["cli", "run"]

#: Commands whose process may end as soon as they succeed, its exit handlers run but not the
#: interpreter's teardown: every file they write is closed (renamed into place) before they
#: return. The teardown frees torch's objects one by one, 0.07 s of a deblur's 2.9 s.
QUICK_END_COMMANDS = frozenset({"deblur"})

_quick_end = False


@click.group(cls=DPGroup, context_settings=CONTEXT)
@click.version_option(__version__, prog_name="dualpixel")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars (for logs and scripts).")
def cli(quiet: bool) -> None:
    """dualpixel: dual-pixel defocus deblurring (Abuolaim et al., ICCV 2021)."""
    global _quick_end
    _quick_end = click.get_current_context().invoked_subcommand in QUICK_END_COMMANDS
    reuse_freed_memory()
    if quiet:
        _silence_progress_bars(click.get_current_context())


def _silence_progress_bars(ctx: click.Context) -> None:
    """Every progress bar of the library is a tqdm bar that follows tqdm's environment
    (:func:`dualpixel.progress.progress_bar`): ``TQDM_DISABLE`` silences them, in worker
    processes too. The setting is undone when the command ends, so a command run from Python
    (a notebook, a test) leaves later ones their bars."""
    before = os.environ.get("TQDM_DISABLE")
    os.environ["TQDM_DISABLE"] = "1"

    def restore() -> None:
        if before is None:
            os.environ.pop("TQDM_DISABLE", None)
        else:
            os.environ["TQDM_DISABLE"] = before

    ctx.call_on_close(restore)


for _module in (synthesis, training, reproduce, adaptation, inference, calibration, demo):
    for _command in _module.COMMANDS:
        cli.add_command(_command)


def run() -> None:
    """The ``dualpixel`` console script and ``python -m dualpixel``: :func:`cli`, after which
    the process ends. A process group that ``torchrun`` training opened is closed, then the
    objects are frozen out of the interpreter's last garbage collections (torch alone makes
    165,000: a third of a second of every command's exit on two cores). After a command of
    :data:`QUICK_END_COMMANDS` that succeeded, with no other thread left to wait for, the exit
    handlers run and the process ends without the teardown. ``cli.main(...)`` called from
    Python (a notebook, click's test runner) leaves all this as it is."""
    code: int | str | None = 0
    try:
        cli()
    except SystemExit as end:  # click's standalone mode ends every command so
        code = end.code
    finally:
        distributed = sys.modules.get("torch.distributed")
        if distributed is not None and distributed.is_available() and \
                distributed.is_initialized():
            distributed.destroy_process_group()
        gc.freeze()
    others = [t for t in threading.enumerate()
              if t is not threading.current_thread() and not t.daemon]
    if code in (0, None) and _quick_end and not others:
        atexit._run_exitfuncs()  # logging's flush, temporary folders, child processes
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe: nothing more to say
                pass
        os._exit(0)
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    run()
