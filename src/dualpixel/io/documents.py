"""Reading the JSON and YAML files users give or jobs leave behind (configs, recipes, camera
files, dataset descriptions): one reader whose errors name the file and what is wrong.

The reader bounds what a hostile file can make it do: at most :data:`MAX_BYTES` of text, nesting
at most :data:`MAX_DEPTH` deep, and at most :data:`MAX_VALUES` values once YAML's aliases are
expanded (a few hundred bytes of aliases can stand for gigabytes of values)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError

__all__ = ["MAX_BYTES", "MAX_DEPTH", "MAX_VALUES", "read_mapping"]

#: Largest document read (bytes): configs, recipes and descriptions are a few kB.
MAX_BYTES = 16 * 1024 * 1024
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 64
#: Most values (mappings, lists and scalars, each alias use counted again).
MAX_VALUES = 1_000_000


def read_mapping(path: str | Path, what: str, *, syntax: str = "json") -> dict[str, Any]:
    """The mapping stored in ``path`` (``syntax`` "json" or "yaml", read with ``safe_load``).

    A missing file, one that is not UTF-8 text, invalid syntax or a document that is not a
    mapping raise :class:`InputFileError` naming the file and ``what`` it should be.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, f"{what} not found")
    if path.stat().st_size > MAX_BYTES:
        raise InputFileError(path, f"is {path.stat().st_size} bytes, more than a {what} can be "
                                   f"({MAX_BYTES} at most)")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputFileError(path, f"is not a text file (expected a {what} in "
                                   f"{syntax.upper()})") from None
    except OSError as error:
        raise InputFileError(path, f"cannot be read ({error.strerror or error})") from None
    try:
        data = _parse(text, syntax)
    except ValueError as error:
        raise InputFileError(path, f"is not valid {syntax.upper()} ({error}); expected a "
                                   f"{what}") from None
    if not isinstance(data, dict):
        raise InputFileError(path, f"expected a {what} (a mapping of keys), got "
                                   f"{type(data).__name__}")
    problem = _too_large(data)
    if problem:
        raise InputFileError(path, f"{problem}; expected a {what}")
    return data


def _too_large(data: Any) -> str | None:
    """What exceeds the bounds in a parsed document (aliases walked as often as they are
    used, with a budget, so an expansion bomb stops early), or None."""
    stack, seen = [(data, 0)], 0
    while stack:
        node, depth = stack.pop()
        seen += 1
        if seen > MAX_VALUES:
            return f"holds more than {MAX_VALUES} values once its aliases are expanded"
        if depth > MAX_DEPTH:
            return f"is nested more than {MAX_DEPTH} levels deep"
        if isinstance(node, dict):
            stack.extend((value, depth + 1) for value in node.values())
        elif isinstance(node, list):
            stack.extend((value, depth + 1) for value in node)
    return None


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
