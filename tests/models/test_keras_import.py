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


def write_keras_file(path, shapes, *, names=None, extra_layers=True, he=False):
    """Conv2D layers (kh, kw, cin, cout) in creation order, interleaved with weightless layers as
    Keras writes them (``model_weights/<layer>/<layer>/kernel:0``); weights of std 0.01, or
    ``he``: He-normal (as the authors initialise), so a signal survives all the layers."""
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
            std = np.sqrt(2.0 / np.prod(shape[:3])) if he else 0.01
            kernel = rng.normal(0, std, shape).astype(np.float32)
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


#: The authors' DPDNet (``DPDNet/model.py`` of their published repository,
#: Abdullah-Abuolaim/defocus-deblurring-dual-pixel): its 24 Conv2D layers as the code creates
#: them, so Keras names them conv2d_1 .. conv2d_24 in this order: (kernel side, in, out). Four
#: encoder levels of two 3x3 convolutions (64-512), two at 1024, then per decoder level a 2x2
#: convolution after 2x nearest upsampling and two 3x3 on [skip, up], a 3x3 to 3 channels and a
#: 1x1 with the sigmoid.
AUTHORS_LAYERS = [
    (3, 6, 64), (3, 64, 64), (3, 64, 128), (3, 128, 128), (3, 128, 256), (3, 256, 256),
    (3, 256, 512), (3, 512, 512), (3, 512, 1024), (3, 1024, 1024),
    (2, 1024, 512), (3, 1024, 512), (3, 512, 512), (2, 512, 256), (3, 512, 256), (3, 256, 256),
    (2, 256, 128), (3, 256, 128), (3, 128, 128), (2, 128, 64), (3, 128, 64), (3, 64, 64),
    (3, 64, 3), (1, 3, 3),
]


def _authors_forward(x: torch.Tensor, layers: list) -> torch.Tensor:
    """The authors' U-Net written from their code with plain torch ops (not our network):
    Keras "same" padding (an even kernel pads one more at the bottom and right), ReLU, max
    pooling, nearest upsampling, concatenation [skip, up], dropout off, sigmoid at the end."""
    import torch.nn.functional as F

    weights = iter(layers)

    def conv(x, act=torch.relu):
        kernel, bias = next(weights)
        total = kernel.shape[0] - 1
        x = F.pad(x, (total // 2, total - total // 2, total // 2, total - total // 2))
        w = torch.from_numpy(kernel).permute(3, 2, 0, 1)
        return act(F.conv2d(x, w, torch.from_numpy(bias)))

    skips = []
    for _ in range(4):
        x = conv(conv(x))
        skips.append(x)
        x = F.max_pool2d(x, 2)
    x = conv(conv(x))
    for skip in reversed(skips):
        up = conv(F.interpolate(x, scale_factor=2, mode="nearest"))
        x = conv(conv(torch.cat([skip, up], dim=1)))
    return conv(conv(x), torch.sigmoid)


def test_a_file_laid_out_as_the_authors_model_imports_to_their_network(tmp_path):
    """Not our own order read back: a file whose layers follow the authors' published model
    (AUTHORS_LAYERS) imports to a network that computes what their architecture computes,
    written independently above, on views of a size that needs no padding."""
    shapes = [(k, k, cin, cout) for k, cin, cout in AUTHORS_LAYERS]
    layers = write_keras_file(tmp_path / "authors.hdf5", shapes, he=True)
    net = import_keras_dpdnet(tmp_path / "authors.hdf5").eval()
    views = torch.rand(1, 6, 32, 48, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        ours, _ = net.step(views)
        theirs = _authors_forward(views, layers)
    assert float(theirs.std()) > 0.01  # a signal, not a saturated or constant output
    torch.testing.assert_close(ours, theirs, atol=1e-5, rtol=1e-4)


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
