"""Reading the JSON and YAML files users give or jobs leave behind (configs, recipes, camera
files, dataset descriptions): one reader whose errors name the file and what is wrong."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dualpixel.errors import InputFileError

__all__ = ["read_mapping"]


def read_mapping(path: str | Path, what: str, *, syntax: str = "json") -> dict[str, Any]:
    """The mapping stored in ``path`` (``syntax`` "json" or "yaml", read with ``safe_load``).

    A missing file, one that is not UTF-8 text, invalid syntax or a document that is not a
    mapping raise :class:`InputFileError` naming the file and ``what`` it should be.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, f"{what} not found")
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
    return data


def _parse(text: str, syntax: str) -> Any:
    """Parse ``text``; a syntax error is a ``ValueError`` with the parser's first line."""
    if syntax == "json":
        return json.loads(text)
    import yaml

    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ValueError(str(error).splitlines()[0]) from None
    return {} if data is None else data
