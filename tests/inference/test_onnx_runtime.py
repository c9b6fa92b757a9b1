"""The ONNX Runtime backend: same outputs as PyTorch in fp32, graphs cached per
checkpoint, clear refusals."""

import importlib.util

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.inference import Deblurrer
from dualpixel.models import build_model

pytest.importorskip("onnxruntime")
pytest.importorskip("onnxscript")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """One cache folder for the module (each export takes seconds)."""
    folder = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("DUALPIXEL_CACHE_DIR", str(folder))
        yield folder / "onnx"


def _frames(count, height, width, seed=0):
    rng = np.random.default_rng(seed)
    return [(rng.random((height, width, 3), dtype=np.float32),
             rng.random((height, width, 3), dtype=np.float32)) for _ in range(count)]


@pytest.mark.parametrize("options", [{}, {"tile": 32, "flips": True}])
def test_onnxruntime_matches_torch_fp32_across_frames(refined_model, cache, options):
    """Two frames of a sequence (the state carried) at a size that is no multiple of 16; tiles
    and flips go through the graph as batches (its batch size is dynamic)."""
    reference = Deblurrer(refined_model, precision="fp32", **options)
    runtime = Deblurrer(refined_model, backend="onnxruntime", **options)
    assert runtime.numerics.name == "fp32"
    for left, right in _frames(2, 50, 70):
        expected, got = reference(left, right), runtime(left, right)
        assert got.shape == (50, 70, 3)
        assert np.abs(got - expected).max() < 1e-4
    assert runtime._net.path.parent == cache


def test_graphs_are_cached_per_weights(refined_model, cache):
    first = Deblurrer(refined_model, backend="onnxruntime")._net.path
    stamp = first.stat().st_mtime_ns
    again = Deblurrer(refined_model, backend="onnxruntime")._net.path
    assert again == first and first.stat().st_mtime_ns == stamp  # found, not exported again
    other = build_model("rdpd", width=0.125, residual=True, refiner=(8, 16, 16)).eval()
    assert Deblurrer(other, backend="onnxruntime")._net.path != first
    assert all(p.suffix == ".onnx" for p in cache.iterdir())  # no leftovers of the writes


@pytest.mark.parametrize("conv_bottleneck", [False, True])
def test_single_frame_model_uses_the_frame_graph(cache, tmp_path, conv_bottleneck):
    """A ConvLSTM network trained on frames, and one with DPDNet's bottleneck in its place
    (no state at all), run through the frame graph; the graph file rebuilds the latter."""
    from dualpixel.inference.onnx_export import export_onnx
    from dualpixel.inference.onnx_runtime import load_onnx_checkpoint

    torch.manual_seed(0)
    model = build_model("rdpd", width=0.125, residual=True,
                        conv_bottleneck=conv_bottleneck).eval()
    model.temporal = False  # as a model trained on single frames is marked
    (left, right), = _frames(1, 40, 44, seed=1)
    expected = Deblurrer(model, precision="fp32")(left, right)
    got = Deblurrer(model, backend="onnxruntime")(left, right)
    assert np.abs(got - expected).max() < 1e-4
    graph = tmp_path / "frame.onnx"
    export_onnx(model, graph, height=32, width=32)
    assert load_onnx_checkpoint(graph).conv_bottleneck is conv_bottleneck


def test_refusals(refined_model, cache, monkeypatch):
    before = sorted(cache.glob("*")) if cache.exists() else []
    with pytest.raises(ParameterError, match="runs in fp32"):
        Deblurrer(refined_model, backend="onnxruntime", precision="bf16")
    with pytest.raises(ParameterError, match="runs on the CPU"):
        Deblurrer(refined_model, backend="onnxruntime", device="cuda")
    with pytest.raises(ParameterError, match="backend must be one of"):
        Deblurrer(refined_model, backend="tensorrt")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "onnxruntime" else real(name, *a))
    with pytest.raises(ParameterError, match=r"needs onnxruntime: pip install 'dualpixel\[onnx\]'"):
        Deblurrer(refined_model, backend="onnxruntime")
    assert (sorted(cache.glob("*")) if cache.exists() else []) == before  # refused first


def test_deblur_command_backend(tiny_checkpoint, cache, tmp_path):
    rng = np.random.default_rng(2)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 255, (36, 52, 3), np.uint8))
    outputs = {}
    for backend in ("torch", "onnxruntime"):
        out = tmp_path / f"{backend}.png"
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
            "--output", str(out), "--checkpoint", str(tiny_checkpoint), "--precision", "fp32",
            "--backend", backend])
        assert result.exit_code == 0, result.output
        outputs[backend] = cv2.imread(str(out)).astype(int)
    assert np.abs(outputs["torch"] - outputs["onnxruntime"]).max() <= 1  # 8-bit rounding
    bad = CliRunner().invoke(cli, [
        "deblur", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
        "--output", str(tmp_path / "x.png"), "--checkpoint", str(tiny_checkpoint),
        "--backend", "onnxruntime", "--precision", "bf16"])
    assert bad.exit_code == 2 and "runs in fp32" in bad.output and "Traceback" not in bad.output


def test_deblur_runs_an_exported_graph(tiny_checkpoint, tmp_path):
    from dualpixel.inference.onnx_export import export_onnx, graph_metadata
    from dualpixel.models import load_model

    graph = tmp_path / "tiny.onnx"
    export_onnx(load_model(tiny_checkpoint), graph, height=32, width=48, batch=2)
    assert graph_metadata(graph)["model"] == "rdpd"
    rng = np.random.default_rng(3)
    for name in ("l", "r"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 255, (40, 56, 3), np.uint8))
    outputs = {}
    for checkpoint in (tiny_checkpoint, graph):
        out = tmp_path / f"{checkpoint.suffix[1:]}.png"
        result = CliRunner().invoke(cli, [
            "deblur", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
            "--output", str(out), "--checkpoint", str(checkpoint), "--precision", "fp32"])
        assert result.exit_code == 0, result.output
        outputs[checkpoint.suffix] = cv2.imread(str(out)).astype(int)
    assert np.abs(outputs[".safetensors"] - outputs[".onnx"]).max() <= 1  # 8-bit rounding
    # a graph without the network's description, and a file that is no graph, are refused
    stray = tmp_path / "stray.onnx"
    stray.write_bytes(b"not a graph")
    bad = CliRunner().invoke(cli, [
        "deblur", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
        "--output", str(tmp_path / "x.png"), "--checkpoint", str(stray)])
    assert bad.exit_code == 1 and "stray.onnx" in bad.output and "Traceback" not in bad.output
