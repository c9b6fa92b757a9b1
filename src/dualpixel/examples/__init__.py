"""Example files shipped with the package, usable by name where a file is asked for:
``dualpixel train --config finetune`` (:func:`example_config`)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["example_config", "example_names"]


def example_names() -> list[str]:
    """The names of the shipped example training configs."""
    folder = resources.files(__name__)
    return sorted(Path(str(entry)).stem for entry in folder.iterdir()
                  if str(entry).endswith(".yaml"))


def example_config(name: str) -> Path | None:
    """The file of the shipped example config ``name`` (e.g. ``finetune``), or None.

    >>> example_config("finetune").name
    'finetune.yaml'
    """
    path = Path(str(resources.files(__name__))) / f"{name}.yaml"
    return path if name in example_names() and path.is_file() else None
