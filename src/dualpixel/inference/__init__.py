"""Inference: deblurring frames and sequences at full resolution, tiled when memory is short."""

from dualpixel.inference.deblur import Deblurrer, deblur_sequence, load_sequence_frames
from dualpixel.inference.tiling import TileGrid, deblur_tiled

__all__ = ["Deblurrer", "TileGrid", "deblur_sequence", "deblur_tiled", "load_sequence_frames"]
