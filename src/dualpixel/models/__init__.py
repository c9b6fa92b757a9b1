"""Deblurring networks: RDPD (ConvLSTM U-Net), DPDNet and variants, and their checkpoints."""

from dualpixel.models.checkpoint import load_model, load_weights, read_metadata, save_model
from dualpixel.models.convlstm import ConvLSTMCell, LSTMState
from dualpixel.models.registry import (
    ARCHITECTURES,
    MODELS,
    ModelSpec,
    build_architecture,
    build_model,
    count_parameters,
    model_spec,
)
from dualpixel.models.unet import DeblurNet, NetworkShape, pad_to_multiple

__all__ = [
    "ARCHITECTURES",
    "MODELS",
    "ConvLSTMCell",
    "DeblurNet",
    "LSTMState",
    "ModelSpec",
    "NetworkShape",
    "build_architecture",
    "build_model",
    "count_parameters",
    "load_model",
    "load_weights",
    "model_spec",
    "pad_to_multiple",
    "read_metadata",
    "save_model",
]
