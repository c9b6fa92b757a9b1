"""Importing the authors' published Keras DPDNet weights (``.hdf5``) into our checkpoints.

Abuolaim & Brown's DPDNet (ECCV 2020) is the network of our ``dpdnet`` preset, layer for layer:
the same convolutions in the same order, concatenations with the skip first, 2x2 "same"
up-convolutions padded right and bottom, a 3x3 ReLU and a 1x1 sigmoid head. Keras stores the
layers' kernels as ``(kh, kw, c_in, c_out)`` in creation order (``layer_names``); the importer
takes every convolution kernel in that order, maps it onto our convolutions in the same creation
order and transposes it to PyTorch's ``(c_out, c_in, kh, kw)``. Needs ``h5py``
(``pip install 'dualpixel[keras]'``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.models.registry import build_model
from dualpixel.models.unet import DeblurNet

__all__ = ["import_keras_dpdnet", "keras_creation_order"]


def keras_creation_order(model: DeblurNet) -> list[nn.Conv2d]:
    """Our convolutions in the order the Keras model creates its layers: encoder levels, the
    bottleneck, then per decoder level the up-convolution and its two convolutions, the head."""
    if model.lstm is not None:
        raise ParameterError("only the feed-forward DPDNet variants have a Keras original")

    def convs(module: nn.Module) -> list[nn.Conv2d]:
        return [m for m in module.modules() if isinstance(m, nn.Conv2d)]

    order = [conv for encoder in model.encoders for conv in convs(encoder)]
    order += convs(model.bottleneck)
    for upconv, decoder in zip(model.upconvs, model.decoders):
        order += convs(upconv) + convs(decoder)
    return order + convs(model.head)


def _read_kernels(path: Path) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(layer name, kernel, bias)`` of every convolution in ``layer_names`` order."""
    try:
        import h5py
    except ImportError:
        raise ParameterError("importing Keras weights needs h5py: pip install 'dualpixel[keras]'"
                             ) from None
    if not path.is_file():
        raise InputFileError(path, "file not found")
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise InputFileError(path, f"not an HDF5 file ({error})") from None
    with handle:
        root = handle["model_weights"] if "model_weights" in handle else handle
        if "layer_names" not in root.attrs:
            raise InputFileError(path, "not a Keras weights file (no layer_names attribute)")
        layers = []
        for raw in root.attrs["layer_names"]:
            name = raw.decode() if isinstance(raw, bytes) else str(raw)
            group = root[name]
            weights = [w.decode() if isinstance(w, bytes) else str(w)
                       for w in group.attrs.get("weight_names", [])]
            kernels = [w for w in weights if w.split("/")[-1].startswith("kernel")]
            if not kernels:
                continue  # pooling, dropout, concatenation, input ...
            array = np.asarray(group[kernels[0]])
            if array.ndim != 4:
                continue
            biases = [w for w in weights if w.split("/")[-1].startswith("bias")]
            bias = np.asarray(group[biases[0]]) if biases else np.zeros(array.shape[-1])
            layers.append((name, array, bias))
    return layers


def import_keras_dpdnet(path: str | Path, *, model: str = "dpdnet") -> DeblurNet:
    """Our ``model`` (``dpdnet`` or ``dpdnet-single``) with the weights of a Keras ``.hdf5``;
    errors name the file and the layer that does not fit. Save it with
    :func:`dualpixel.models.save_model` to use it in every command."""
    path = Path(path)
    net = build_model(model)
    targets = keras_creation_order(net)
    layers = _read_kernels(path)
    if len(layers) != len(targets):
        raise InputFileError(path, f"holds {len(layers)} convolution layers; {model} has "
                                   f"{len(targets)}")
    with torch.no_grad():
        for (name, kernel, bias), conv in zip(layers, targets):
            expected = (conv.kernel_size[0], conv.kernel_size[1], conv.in_channels,
                        conv.out_channels)
            if kernel.shape != expected or bias.shape != (conv.out_channels,):
                raise InputFileError(path, f"layer {name}: kernel {kernel.shape}, expected "
                                           f"{expected} (kh, kw, c_in, c_out)")
            conv.weight.copy_(torch.from_numpy(kernel.transpose(3, 2, 0, 1).copy()))
            conv.bias.copy_(torch.from_numpy(bias.astype(np.float32)))
    return net.eval()
