"""Synthetic dual-pixel data (paper Sec. 3): layered rendering, procedural scenes, datasets."""

from dualpixel.synthesis.frame import DPFrame, SequenceDraw, draw_sequence, synthesize_frame
from dualpixel.synthesis.renderer import render_dp_views

__all__ = ["DPFrame", "SequenceDraw", "draw_sequence", "render_dp_views", "synthesize_frame"]

#: Old names (a "recipe" is a model's YAML file; what synthesis draws for a sequence is its
#: draw), importable with a warning until release 0.3.
_RENAMED = {"SequenceRecipe": "SequenceDraw", "draw_recipe": "draw_sequence"}


def __getattr__(name: str):
    if name in _RENAMED:
        import warnings

        from dualpixel.names import RENAMED_UNTIL

        warnings.warn(f"dualpixel.synthesis.{name} is now {_RENAMED[name]}; the old name goes "
                      f"in release {RENAMED_UNTIL}", FutureWarning, stacklevel=2)
        return globals()[_RENAMED[name]]
    raise AttributeError(f"module 'dualpixel.synthesis' has no attribute {name!r}")
