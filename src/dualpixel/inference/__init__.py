"""Inference: deblurring frames and sequences at full resolution."""

from dualpixel.inference.deblur import deblur_frame, deblur_sequence, load_sequence_frames

__all__ = ["deblur_frame", "deblur_sequence", "load_sequence_frames"]
