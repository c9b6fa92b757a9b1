"""Inference: deblurring frames and sequences at full resolution, tiled when memory is short."""

from dualpixel.inference.deblur import Deblurrer, deblur_sequence, load_sequence_frames
from dualpixel.inference.pipeline import build_deblurrer, load_network
from dualpixel.inference.tiling import TileGrid, deblur_tiled

__all__ = ["Deblurrer", "TileGrid", "build_deblurrer", "deblur_sequence", "deblur_tiled",
           "load_network", "load_sequence_frames"]
