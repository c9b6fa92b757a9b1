"""The importer of the authors' Keras DPDNet weights, on a file in Keras's HDF5 layout that the
test writes with h5py."""

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.models import build_model, count_parameters, load_model
from dualpixel.models.keras_import import import_keras_dpdnet, keras_creation_order

h5py = pytest.importorskip("h5py")


def write_keras_file(path, shapes, *, names=None, extra_layers=True):
    """Conv2D layers (kh, kw, cin, cout) in creation order, interleaved with weightless layers as
    Keras writes them (``model_weights/<layer>/<layer>/kernel:0``)."""
    rng = np.random.default_rng(0)
    kernels = []
    names = names or [f"conv2d_{i + 1}" for i in range(len(shapes))]
    layer_names = []
    with h5py.File(path, "w") as handle:
        root = handle.create_group("model_weights")
        for index, (name, shape) in enumerate(zip(names, shapes)):
            if extra_layers and index % 2 == 1:
                pool = f"max_pooling2d_{index}"
                root.create_group(pool).attrs["weight_names"] = np.array([], dtype="S")
                layer_names.append(pool)
            group = root.create_group(name).create_group(name)
            kernel = rng.normal(0, 0.01, shape).astype(np.float32)
            bias = rng.normal(0, 0.01, shape[-1]).astype(np.float32)
            group["kernel:0"], group["bias:0"] = kernel, bias
            root[name].attrs["weight_names"] = np.array(
                [f"{name}/kernel:0".encode(), f"{name}/bias:0".encode()])
            layer_names.append(name)
            kernels.append((kernel, bias))
        root.attrs["layer_names"] = np.array([n.encode() for n in layer_names])
    return kernels


def keras_shapes():
    return [(c.kernel_size[0], c.kernel_size[1], c.in_channels, c.out_channels)
            for c in keras_creation_order(build_model("dpdnet"))]


def test_import_maps_every_layer_in_creation_order(tmp_path):
    shapes = keras_shapes()
    assert len(shapes) == 24  # 8 encoder + 2 bottleneck + 4 x 3 decoder + 2 head convolutions
    # Keras numbers layers by creation: conv2d_10 comes after conv2d_9, not after conv2d_1.
    kernels = write_keras_file(tmp_path / "dpdnet.hdf5", shapes)
    net = import_keras_dpdnet(tmp_path / "dpdnet.hdf5")
    for (kernel, bias), conv in zip(kernels, keras_creation_order(net)):
        np.testing.assert_array_equal(conv.weight.detach().numpy(), kernel.transpose(3, 2, 0, 1))
        np.testing.assert_array_equal(conv.bias.detach().numpy(), bias)
    keras_parameters = sum(k.size + b.size for k, b in kernels)
    assert keras_parameters == count_parameters(net)  # the same network, parameter for parameter


def test_import_command_and_clear_errors(tmp_path):
    shapes = keras_shapes()
    write_keras_file(tmp_path / "dpdnet.hdf5", shapes)
    result = CliRunner().invoke(cli, ["import-keras", str(tmp_path / "dpdnet.hdf5"), "--output",
                                      str(tmp_path / "dpdnet.safetensors")])
    assert result.exit_code == 0, result.output
    model = load_model(tmp_path / "dpdnet.safetensors")
    with torch.no_grad():
        out, _ = model.step(torch.rand(1, 6, 32, 48))  # left and right views
    assert out.shape == (1, 3, 32, 48)
    write_keras_file(tmp_path / "short.hdf5", shapes[:-1])
    short = CliRunner().invoke(cli, ["import-keras", str(tmp_path / "short.hdf5"), "--output",
                                     str(tmp_path / "x.safetensors")])
    assert short.exit_code == 1 and "short.hdf5" in short.output
    assert "23 convolution" in short.output
    wrong = list(shapes)
    wrong[3] = (3, 3, 64, 99)
    write_keras_file(tmp_path / "wrong.hdf5", wrong)
    with pytest.raises(ValueError, match=r"wrong.hdf5: layer conv2d_4: kernel \(3, 3, 64, 99\)"):
        import_keras_dpdnet(tmp_path / "wrong.hdf5")
