"""Training: losses (Eq. 13-16), configuration and the alternating training loop (Sec. 5)."""

from dualpixel.training.config import TrainConfig, load_config, save_config
from dualpixel.training.losses import DeblurLoss, EdgeLoss, sobel_factors, sobel_kernels
from dualpixel.training.trainer import TrainResult, train, weight_average

__all__ = [
    "DeblurLoss",
    "EdgeLoss",
    "TrainConfig",
    "TrainResult",
    "load_config",
    "save_config",
    "sobel_factors",
    "sobel_kernels",
    "train",
    "weight_average",
]
