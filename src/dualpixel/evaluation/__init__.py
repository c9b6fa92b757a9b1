"""Evaluation: image-quality metrics, NIQE, result tables, PSNR by blur size and comparison
figures."""

from dualpixel.evaluation.blur_breakdown import BlurBreakdown
from dualpixel.evaluation.metrics import mae, psnr, ssim

__all__ = ["BlurBreakdown", "mae", "psnr", "ssim"]
