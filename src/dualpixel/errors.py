"""Typed errors and the validation helpers used at every public boundary (ranges, seeds).

Messages always say what was expected and what came, and name the parameter or file.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = [
    "SEED_MAX",
    "DualPixelError",
    "InputFileError",
    "OutputFileError",
    "ParameterError",
    "check_integer",
    "check_range",
    "check_seed",
    "is_integer",
]


class DualPixelError(Exception):
    """Base class of every error this package raises on purpose."""


class ParameterError(DualPixelError, ValueError):
    """A parameter is outside its allowed range or of the wrong kind."""


class InputFileError(DualPixelError, ValueError):
    """An input file is missing, unreadable or has the wrong content; the message names the file."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")

    def __reduce__(self):  # pickled whole, so a worker process's error reaches its parent
        return type(self), (self.path, self.problem)


class OutputFileError(DualPixelError, OSError):
    """An output cannot be written (a folder, no permission, disk full); names the path."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}"

    def __reduce__(self):  # pickled whole, so a worker process's error reaches its parent
        return type(self), (self.path, self.problem)


def check_range(
    name: str,
    value: float,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_inclusive: bool = True,
    high_inclusive: bool = True,
) -> float:
    """Return ``value`` as a float if it lies in the interval, else raise :class:`ParameterError`.

    >>> check_range("beta", 0.2, 0.0, 1.0, low_inclusive=False)
    0.2
    """
    if isinstance(value, bool):  # float(True) is 1.0: a flag is not a number
        raise ParameterError(f"{name} must be a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {value!r}") from None
    except OverflowError:
        raise ParameterError(f"{name} must be a number of at most 308 digits, got one of "
                             f"{len(str(value))}") from None
    if not math.isfinite(number):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    above = number >= low if low_inclusive else number > low
    below = number <= high if high_inclusive else number < high
    if not (above and below):
        opening, closing = "[" if low_inclusive else "(", "]" if high_inclusive else ")"
        interval = f"{opening}{low:g}, {high:g}{closing}"
        raise ParameterError(f"{name} must be in {interval}, got {value!r}")
    return number


def is_integer(value: object) -> bool:
    """Whether ``value`` is a Python or NumPy integer (a ``bool`` is not one here).

    >>> is_integer(3), is_integer(True), is_integer(3.0)
    (True, False, False)
    """
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def check_integer(name: str, value: object, low: int = 0, high: int = 2**63 - 1) -> int:
    """Return ``value`` as an int if it is an integer (a ``bool`` or a float is not) in
    [``low``, ``high``], else raise :class:`ParameterError` naming ``name``.

    >>> check_integer("width", 840, 1, 65536)
    840
    """
    if not is_integer(value):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    if not low <= int(value) <= high:
        shown = value if len(str(value)) <= 40 else f"an integer of {len(str(value))} digits"
        raise ParameterError(f"{name} must be in [{low}, {high}], got {shown}")
    return int(value)


#: The largest seed any command or function takes (a non-negative 63-bit integer, what NumPy's
#: and torch's generators both accept).
SEED_MAX = 2**63 - 1


def check_seed(name: str, value: object) -> int:
    """Return ``value`` if it is an integer seed in [0, :data:`SEED_MAX`], else raise
    :class:`ParameterError` naming ``name``.

    >>> check_seed("seed", 7)
    7
    """
    if not is_integer(value):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    if not 0 <= int(value) <= SEED_MAX:
        raise ParameterError(f"{name} must be in [0, 2**63 - 1], got {value}")
    return int(value)
