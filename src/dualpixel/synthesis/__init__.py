"""Synthetic dual-pixel data (paper Sec. 3): layered rendering, procedural scenes, datasets."""

from dualpixel.names import renamed_attributes
from dualpixel.synthesis.frame import DPFrame, SequenceDraw, draw_sequence, synthesize_frame
from dualpixel.synthesis.renderer import render_dp_views

__all__ = ["DPFrame", "SequenceDraw", "draw_sequence", "render_dp_views", "synthesize_frame"]

#: Old names (a "recipe" is a model's YAML file; what synthesis draws for a sequence is its
#: draw), importable with a warning until release 0.3.
__getattr__ = renamed_attributes(
    __name__, {"SequenceRecipe": "SequenceDraw", "draw_recipe": "draw_sequence"}, globals())
