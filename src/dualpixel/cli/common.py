"""What every command shares: error reporting, context settings and option parsers.

Error contract of the ``dualpixel`` command (README "What the commands guarantee"):

- a bad option value (:class:`~dualpixel.errors.ParameterError`, click's own checks) is a usage
  error: the subcommand's usage line, one message, exit status 2;
- any other failure the library reports on purpose (a bad input file, an unwritable output, not
  enough memory or disk) prints ``Error: <path>: <problem>`` and exits with status 1;
- neither prints a Python traceback.

Warnings of the library (``warnings.warn``) print as ``Warning: <message>`` on stderr, above
any progress bar, without Python's file and line.
"""

from __future__ import annotations

import errno
import sys
import warnings
from pathlib import Path

import click

from dualpixel.errors import SEED_MAX, DualPixelError, ParameterError
from dualpixel.io.paths import broken_link, check_outputs_apart

__all__ = ["CONTEXT", "MAX_SIDE", "SEED", "DPCommand", "DPGroup", "OutputPath", "float_list",
           "parse_size"]

CONTEXT = {"help_option_names": ["-h", "--help"], "show_default": True}
#: The type of every ``--seed`` option: what :func:`dualpixel.errors.check_seed` takes.
SEED = click.IntRange(0, SEED_MAX)


def _os_error_message(error: OSError) -> str:
    where = error.filename if error.filename is not None else "output"
    if error.errno == errno.ENOSPC:
        return f"{where}: no space left on device"
    if isinstance(error, PermissionError):
        return f"{where}: permission denied (not writable or readable by this user)"
    return f"{where}: {error.strerror or error}"


def _report(error: BaseException, ctx: click.Context) -> click.ClickException:
    """The click exception that reports ``error`` for the command of ``ctx``."""
    if isinstance(error, ParameterError):
        return click.UsageError(str(error), ctx)
    if isinstance(error, DualPixelError):
        return click.ClickException(str(error))
    if isinstance(error, MemoryError):
        return click.ClickException(
            "not enough memory for this request; use smaller images, --tile or fewer workers"
        )
    assert isinstance(error, OSError)
    return click.ClickException(_os_error_message(error))


class InputPath(click.Path):
    """An existing file or folder option: a symbolic link that loops or leads nowhere is said
    to be one (click would call it missing)."""

    def convert(self, value, param, ctx):
        problem = broken_link(value) if isinstance(value, (str, Path)) else None
        if problem:
            self.fail(f"{value}: {problem}", param, ctx)
        return super().convert(value, param, ctx)


class OutputPath(click.Path):
    """A path the command writes (a file or folder option). Every other path option, and a
    checkpoint given as an existing file, is an input: :class:`DPCommand` refuses an output that
    is an input, holds one or lies inside an input folder, before any work."""


#: Options whose string value is an input file when it names one (a checkpoint or camera file,
#: not a shipped name).
_FILE_OR_NAME_OPTIONS = ("checkpoint", "checkpoints", "niqe_model", "camera_file")


def _paths_of(ctx: click.Context) -> tuple[dict[str, list[Path]], dict[str, Path]]:
    """The inputs and outputs of a parsed command line, by option (``--left``)."""
    inputs: dict[str, list[Path]] = {}
    outputs: dict[str, Path] = {}
    for param in ctx.command.params:
        value = ctx.params.get(param.name)
        if value is None or not isinstance(param, (click.Option, click.Argument)):
            continue
        option = param.opts[0] if isinstance(param, click.Option) else param.human_readable_name
        values = value if isinstance(value, (tuple, list)) else (value,)
        if isinstance(param.type, OutputPath):
            outputs[option] = Path(values[0])
        elif isinstance(param.type, click.Path) or param.name in _FILE_OR_NAME_OPTIONS:
            inputs[option] = [Path(v) for v in values if isinstance(v, (str, Path))]
    return inputs, outputs


#: The package's folder: warnings raised from code in it are the library's own.
_PACKAGE = str(Path(__file__).resolve().parents[1])


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` for the command: the library's warnings as their message alone,
    above progress bars; other packages' notices of their own API changes (deprecations) are
    not the user's to act on and are left out; anything else as Python prints it."""
    from tqdm import tqdm

    if str(filename).startswith(_PACKAGE):
        tqdm.write(f"Warning: {message}", file=sys.stderr)
    elif not issubclass(category, (DeprecationWarning, PendingDeprecationWarning,
                                   FutureWarning)):
        tqdm.write(warnings.formatwarning(message, category, filename, lineno, line).rstrip(),
                   file=sys.stderr)


class DPCommand(click.Command):
    """A command whose library errors end in one clear message (see the module docstring),
    and whose outputs are never its inputs (:class:`OutputPath`)."""

    def invoke(self, ctx: click.Context):
        try:
            check_outputs_apart(*_paths_of(ctx))
            with warnings.catch_warnings():
                warnings.showwarning = _show_warning
                return super().invoke(ctx)
        except (DualPixelError, MemoryError, OSError) as error:
            raise _report(error, ctx) from error


class DPGroup(click.Group):
    """A group whose commands and subgroups are :class:`DPCommand` / :class:`DPGroup`."""

    command_class = DPCommand
    group_class = type  # subgroups are of this class too

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except (DualPixelError, MemoryError, OSError) as error:  # errors while resolving
            raise _report(error, ctx) from error


def float_list(_ctx, param, value: str | None) -> list[float] | None:
    """Parse ``"1,2.5,3"``; refuse NaN and infinity (a click callback)."""
    if value is None:
        return None
    try:
        numbers = [float(v) for v in value.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}",
                                 param=param) from None
    if any(n != n or n in (float("inf"), float("-inf")) for n in numbers):
        raise click.BadParameter(f"numbers must be finite, got {value!r}", param=param)
    return numbers


#: Largest side (px) an option may ask a command to make: 16384 (a 64 MP frame is 9248 px wide).
MAX_SIDE = 16384


def parse_size(_ctx, param, value: str) -> tuple[int, int]:
    """Parse ``WIDTHxHEIGHT`` into positive integers (a click callback)."""
    try:
        width, height = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WIDTHxHEIGHT, e.g. 320x240, got {value!r}",
                                 param=param) from None
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):
        raise click.BadParameter(f"width and height must be between 1 and {MAX_SIDE}, got "
                                 f"{value!r}", param=param)
    return width, height
