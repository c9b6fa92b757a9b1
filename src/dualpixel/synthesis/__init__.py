"""Synthetic dual-pixel data (paper Sec. 3): layered rendering, procedural scenes, datasets."""

from dualpixel.synthesis.frame import DPFrame, SequenceDraw, draw_sequence, synthesize_frame
from dualpixel.synthesis.renderer import render_dp_views

__all__ = ["DPFrame", "SequenceDraw", "draw_sequence", "render_dp_views", "synthesize_frame"]

#: Old names (a "recipe" is a model's YAML file; what synthesis draws for a sequence is its
#: draw), importable with a warning until release 0.3.
_RENAMED = {"SequenceRecipe": "SequenceDraw", "draw_recipe": "draw_sequence"}


def __getattr__(name: str):
    if name in _RENAMED:
        from dualpixel.names import warn_renamed

        warn_renamed(f"dualpixel.synthesis.{name}", _RENAMED[name], stacklevel=2)
        return globals()[_RENAMED[name]]
    raise AttributeError(f"module 'dualpixel.synthesis' has no attribute {name!r}")
