"""Evaluation: image-quality metrics, NIQE, result tables and comparison figures."""

from dualpixel.evaluation.metrics import mae, psnr, ssim

__all__ = ["mae", "psnr", "ssim"]
