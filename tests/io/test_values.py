"""Issue #34 items 5 and 6: values checked at the boundary; resource errors name the user's path.

Cases from the issue (int32 images, floats up to 1.4, NaN and 1e9 noise, a NaN weight, complex
depth, declared 20000x20000 PNGs, a full disk under safetensors and torch.save) and our own (int8,
a tensor of infinities, a huge TIFF header, the niqe model on a full disk).
"""

from __future__ import annotations

import os
import struct
import tempfile
import types
import zlib

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel import api
from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, OutputFileError, ParameterError
from dualpixel.evaluation.metrics import psnr
from dualpixel.io.images import read_depth, read_rgb
from dualpixel.models import build_model, load_model
from dualpixel.models.checkpoint import save_model


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.int8, np.uint32])
def test_ambiguous_integer_images_are_refused(dtype):
    image = np.full((8, 8, 3), 100, dtype)
    with pytest.raises(ParameterError, match=f"{np.dtype(dtype).name} images are ambiguous"):
        psnr(image, image)


def test_floats_outside_the_unit_range_are_refused_and_overshoot_clipped():
    ones = np.ones((16, 16, 3))
    with pytest.raises(ParameterError, match=r"must lie in \[0, 1\], got \[1.4, 1.4\]"):
        psnr(ones * 1.4, ones)
    broken = torch.ones(3, 16, 16)
    broken[0, 2, 3], broken[2, 5, 5] = float("inf"), float("nan")
    with pytest.raises(ParameterError, match="prediction: has 2 NaN or infinite"):
        psnr(broken, ones)
    assert psnr(ones * (1 + 0.5 / 255), ones) == float("inf")  # a network's overshoot: clipped


@pytest.mark.parametrize("sigmas", [(float("nan"),), (1e9,), (-0.1,), ()])
def test_noise_levels_are_checked(sigmas):
    with pytest.raises(ParameterError, match="noise_sigmas"):
        api.synthesize(np.full((16, 16, 3), 0.5), np.full((16, 16), 2.0), noise_sigmas=sigmas,
                       camera="set0")


def test_complex_depth_is_refused(tmp_path):
    depth = np.full((16, 16), 2.0 + 1j)
    with pytest.raises(ParameterError, match="real numbers"):
        api.synthesize(np.full((16, 16, 3), 0.5), depth, camera="set0")
    np.save(tmp_path / "d.npy", depth)
    with pytest.raises(InputFileError, match=r"d\.npy: depth must hold real numbers"):
        read_depth(tmp_path / "d.npy")


@pytest.mark.parametrize("value, problem", [(float("nan"), "1 NaN/inf values"),
                                            (0.0, "1 zero or negative values")])
def test_bad_depth_gets_the_same_problem_from_the_api_and_from_a_file(tmp_path, value, problem):
    depth = np.full((16, 16), 2.0)
    depth[3, 4] = value
    with pytest.raises(ParameterError, match=problem):
        api.synthesize(np.full((16, 16, 3), 0.5), depth, camera="set0")
    np.save(tmp_path / "d.npy", depth)
    with pytest.raises(InputFileError, match=rf"d\.npy: depth has {problem}"):
        read_depth(tmp_path / "d.npy")


def test_a_checkpoint_with_one_nan_weight_is_refused(tmp_path):
    model = build_model("rdpd", width=0.125)
    with torch.no_grad():
        next(model.parameters()).view(-1)[3] = float("nan")
    save_model(tmp_path / "bad.safetensors", model)
    with pytest.raises(InputFileError, match=r"bad\.safetensors: tensor \S+ has 1 NaN"):
        load_model(tmp_path / "bad.safetensors")
    left = np.full((32, 32, 3), 128, np.uint8)
    from PIL import Image
    Image.fromarray(left).save(tmp_path / "l.png")
    Image.fromarray(left).save(tmp_path / "r.png")
    result = CliRunner().invoke(cli, ["deblur", "--left", str(tmp_path / "l.png"), "--right",
                                      str(tmp_path / "r.png"), "-o", str(tmp_path / "o.png"),
                                      "--checkpoint", str(tmp_path / "bad.safetensors")])
    assert result.exit_code == 1 and "NaN" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "o.png").exists()


def _png_header(path, width: int, height: int) -> None:
    """A PNG that declares ``width`` x ``height`` and holds almost nothing (a bomb's header)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                     + chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("size", [(20000, 20000), (200000, 100000)])
def test_declared_giant_images_are_refused_with_the_numbers(tmp_path, size, monkeypatch):
    monkeypatch.setattr("dualpixel.memory.available_memory", lambda: 8 * 1024**3)
    bomb = tmp_path / "bomb.png"
    _png_header(bomb, *size)
    with pytest.raises(InputFileError, match=rf"bomb\.png: declares {size[0]}x{size[1]} pixels, "
                                             r"which need about \d+\.\d GiB .* 8\.0 GiB"):
        read_rgb(bomb)
    folder = tmp_path / "set"
    for role in ("source", "target"):
        (folder / "test_c" / role).mkdir(parents=True)
        _png_header(folder / "test_c" / role / "a.png", *size)
    for view in ("l", "r"):
        (folder / f"test_{view}" / "source").mkdir(parents=True)
        _png_header(folder / f"test_{view}" / "source" / "a.png", *size)
    result = CliRunner().invoke(cli, ["eval", "--dataset", str(folder), "--no-niqe", "-o",
                                      str(tmp_path / "report")])
    assert result.exit_code != 0 and "Traceback" not in result.output, result.output
    assert "a.png" in result.output


@pytest.fixture
def full_disk(monkeypatch):
    """``full_disk(stem)``: from then on, atomic writes of files named ``stem.*`` land on
    ``/dev/full`` and fail with ENOSPC, as on a full disk; other writes work."""
    real = tempfile.mkstemp

    def fill(stem: str) -> None:
        def mkstemp(prefix="", suffix="", dir=None):
            if not prefix.startswith(f".{stem}."):
                return real(prefix=prefix, suffix=suffix, dir=dir)
            name = os.path.join(dir, f"{prefix}full{suffix}")
            os.symlink("/dev/full", name)
            return os.open(name, os.O_WRONLY), name
        monkeypatch.setattr("dualpixel.io.atomic.tempfile", types.SimpleNamespace(mkstemp=mkstemp))
    return fill


def test_a_full_disk_under_safetensors_names_the_file_and_keeps_the_old_one(tmp_path, full_disk):
    model = build_model("rdpd", width=0.125)
    target = tmp_path / "model.safetensors"
    save_model(target, model)
    before = target.read_bytes()
    full_disk("model")
    with pytest.raises(OutputFileError, match=r"model\.safetensors: no space left on device"):
        save_model(target, model)
    assert target.read_bytes() == before and sorted(tmp_path.iterdir()) == [target]


def test_a_full_disk_under_training_state_names_it_and_keeps_the_last_good(
        tiny_synthetic_dataset, tmp_path, full_disk):
    from dualpixel.training import train
    from tests.training.test_trainer import tiny_config

    out = tmp_path / "run"
    train(tiny_config(tiny_synthetic_dataset, epochs=1), out, progress=False)
    before = (out / "last_state.pt").read_bytes()
    full_disk("last_state")
    with pytest.raises(OutputFileError, match=r"last_state\.pt: no space left on device"):
        train(tiny_config(tiny_synthetic_dataset, epochs=2), out, resume=True, progress=False)
    assert (out / "last_state.pt").read_bytes() == before
    assert not [p for p in out.iterdir() if p.name.startswith(".") and p.is_symlink()]


@pytest.mark.parametrize(("text", "says"), [
    ("epochs: 1e400\n", "'epochs': '1e400' is not an integer"),
    ("epochs: true\n", "'epochs': True is not an integer"),
    ("val_limit: 2.5\n", "'val_limit': 2.5 is not an integer or null"),
    ("refiner: [a, b]\n", "is not a list of integers or null"),
])
def test_config_types_are_named_in_words(tmp_path, text, says):
    """A config value of the wrong type names the key and the type as a user writes it, never
    Python's ``<class 'int'>``."""
    config = tmp_path / "bad.yaml"
    config.write_text(text)
    result = CliRunner().invoke(cli, ["train", "--config", str(config), "-o",
                                      str(tmp_path / "run")])
    assert result.exit_code == 2 and says in result.output
    assert "<class" not in result.output and "Traceback" not in result.output


def test_a_psf_file_that_is_no_plain_array_never_suggests_unsafe_loading(tmp_path):
    import pickle

    from dualpixel.calibration.measured_psfs import load_measured_psfs

    for name, payload in (("random.npy", os.urandom(2000)),
                          ("objects.npy", b"\x93NUMPY" + pickle.dumps({"a": 1}))):
        path = tmp_path / name
        path.write_bytes(payload)
        with pytest.raises(InputFileError, match=name) as raised:
            load_measured_psfs(path, "left")
        assert "allow_pickle" not in str(raised.value) and "unsafely" not in str(raised.value)
