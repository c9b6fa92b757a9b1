"""Reading the JSON and YAML files users give or jobs leave behind (configs, recipes, camera
files, dataset descriptions): one reader whose errors name the file and what is wrong.

The reader bounds what a hostile file can make it do: at most :data:`MAX_BYTES` of text, nesting
at most :data:`MAX_DEPTH` deep, at most :data:`MAX_VALUES` values once YAML's aliases are
expanded (a few hundred bytes of aliases can stand for gigabytes of values), and every number
finite and within :data:`MAX_NUMBER` (no document of ours needs ``Infinity``, ``NaN`` or an
integer of thousands of digits). Whether a value has the right type for its key (a number, not
``true``) is the reader of that key's business: :func:`dualpixel.errors.check_range` and
:func:`dualpixel.errors.check_integer`."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError

__all__ = ["MAX_BYTES", "MAX_DEPTH", "MAX_NUMBER", "MAX_VALUES", "out_of_bounds",
           "read_mapping", "read_text_file"]

#: Largest document read (bytes): configs, recipes and descriptions are a few kB.
MAX_BYTES = 16 * 1024 * 1024
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 64
#: Most values (mappings, lists and scalars, each alias use counted again).
MAX_VALUES = 1_000_000
#: Largest magnitude of a number in a document (a 63-bit integer: seeds are the largest).
MAX_NUMBER = 2**63 - 1


def read_text_file(path: str | Path, what: str, *, syntax: str | None = None) -> str:
    """The UTF-8 text of ``path`` (at most :data:`MAX_BYTES`): a missing, binary or unreadable
    file raises :class:`InputFileError` naming it and ``what`` it should be (in ``syntax``, e.g.
    ``"JSON"``, where one is expected): the text of :func:`read_mapping`'s documents and of the
    line-based files (category lists, manifests, run histories) their readers parse."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, f"{what} not found")
    if path.stat().st_size > MAX_BYTES:
        raise InputFileError(path, f"is {path.stat().st_size} bytes, more than a {what} can be "
                                   f"({MAX_BYTES} at most)")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        expected = what if syntax is None else f"{what} in {syntax}"
        raise InputFileError(path, f"is not a text file (expected a {expected})") from None
    except OSError as error:
        raise InputFileError(path, f"cannot be read ({error.strerror or error})") from None


def read_mapping(path: str | Path, what: str, *, syntax: str = "json") -> dict[str, Any]:
    """The mapping stored in ``path`` (``syntax`` "json" or "yaml", read with ``safe_load``).

    A missing file, one that is not UTF-8 text, invalid syntax or a document that is not a
    mapping raise :class:`InputFileError` naming the file and ``what`` it should be.
    """
    path = Path(path)
    text = read_text_file(path, what, syntax=syntax.upper())
    try:
        data = _parse(text, syntax)
    except ValueError as error:
        raise InputFileError(path, f"is not valid {syntax.upper()} ({error}); expected a "
                                   f"{what}") from None
    if not isinstance(data, dict):
        raise InputFileError(path, f"expected a {what} (a mapping of keys), got "
                                   f"{type(data).__name__}")
    problem = out_of_bounds(data)
    if problem:
        raise InputFileError(path, f"{problem}; expected a {what}")
    return data


def out_of_bounds(data: Any) -> str | None:
    """What exceeds the bounds in a parsed document or ``--set`` value, naming the key path of
    a bad number, or None (aliases walked as often as they are used, with a budget, so an
    expansion bomb stops early)."""
    stack: list[tuple[Any, tuple]] = [(data, ())]
    seen = 0
    while stack:
        node, where = stack.pop()
        seen += 1
        if seen > MAX_VALUES:
            return f"holds more than {MAX_VALUES} values once its aliases are expanded"
        if len(where) > MAX_DEPTH:
            return f"is nested more than {MAX_DEPTH} levels deep"
        if isinstance(node, dict):
            stack.extend((value, (*where, key)) for key, value in node.items())
        elif isinstance(node, list):
            stack.extend((value, (*where, index)) for index, value in enumerate(node))
        elif isinstance(node, float) and not math.isfinite(node):
            shown = "NaN" if math.isnan(node) else "an infinity"
            return f"{_key_path(where)} is {shown}; numbers must be finite"
        elif isinstance(node, int) and not isinstance(node, bool) and abs(node) > MAX_NUMBER:
            return (f"{_key_path(where)} is an integer of {len(str(abs(node)))} digits; numbers "
                    f"must lie within +-(2**63 - 1)")
    return None


def _key_path(where: tuple) -> str:
    """``psf.alpha`` or ``lens_sets[2]`` for the keys and indices leading to a value."""
    text = ""
    for part in where:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "the document"


def _parse(text: str, syntax: str) -> Any:
    """Parse ``text``; a syntax error is a ``ValueError`` with the parser's first line."""
    try:
        if syntax == "json":
            return json.loads(text)
        import yaml

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as error:
            raise ValueError(str(error).splitlines()[0]) from None
        return {} if data is None else data
    except RecursionError:
        raise ValueError(f"nested too deeply (more than {MAX_DEPTH} levels are refused)") from None
