"""Synthetic dual-pixel data (paper Sec. 3): layered rendering, procedural scenes, datasets."""

from dualpixel.synthesis.frame import DPFrame, SequenceRecipe, draw_recipe, synthesize_frame
from dualpixel.synthesis.renderer import render_dp_views

__all__ = ["DPFrame", "SequenceRecipe", "draw_recipe", "render_dp_views", "synthesize_frame"]
