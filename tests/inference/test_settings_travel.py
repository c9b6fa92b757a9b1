"""Issue #73: the output settings a model runs with travel with its weights, as torchvision's
weights carry their transforms: a shipped name, a copy of its file, a network from
``load_model``, a torch.hub model and an exported ONNX graph all deblur alike."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel import deblur, load_model
from dualpixel.cli.main import cli
from dualpixel.weights import output_settings, resolve_checkpoint

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def pair(behind_focus_frame):
    crop = (slice(32, 96), slice(96, 192))
    return behind_focus_frame["left"][crop], behind_focus_frame["right"][crop]


def test_a_shipped_models_settings_follow_it_everywhere(pair, tmp_path):
    left, right = pair
    name = "rdpd-light.v18"  # runs with brightness tied (its registry row)
    assert output_settings(name) == {"brightness": "tied"}
    by_name = deblur(left, right, model=name, device="cpu")
    copy = tmp_path / "my-copy.safetensors"
    shutil.copy(resolve_checkpoint(name), copy)  # known by its sha256
    net = load_model(name, device="cpu")
    assert net.output_settings == {"brightness": "tied"}
    hub = torch.hub.load(str(ROOT), "rdpd_light_v18", source="local", device="cpu")
    for model in (copy, str(copy), net, hub):
        np.testing.assert_array_equal(deblur(left, right, model=model, device="cpu"), by_name)
    untied = deblur(left, right, model=net, device="cpu", brightness="model")
    assert np.abs(untied - by_name).max() > 1e-4  # the tie does something here


@pytest.fixture(scope="module")
def tied_checkpoint(tmp_path_factory) -> Path:
    """An untrained, non-residual light RDPD (it changes the brightness) whose file says it runs
    with brightness tied."""
    from dualpixel.models import build_model, save_model

    torch.manual_seed(3)
    path = tmp_path_factory.mktemp("tied") / "tied.safetensors"
    save_model(path, build_model("rdpd", width=0.125), extra={"output": {"brightness": "tied"}})
    return path


def test_an_onnx_export_runs_as_its_checkpoint(pair, tied_checkpoint, tmp_path):
    pytest.importorskip("onnxruntime")
    left, right = pair
    for name, image in (("left.png", left), ("right.png", right)):
        cv2.imwrite(str(tmp_path / name), cv2.cvtColor(
            np.rint(image * 255).astype(np.uint8), cv2.COLOR_RGB2BGR))
    runner = CliRunner()
    graph = tmp_path / "tied.onnx"
    result = runner.invoke(cli, ["export", "--checkpoint", str(tied_checkpoint), "-o",
                                 str(graph), "--size", "96x64"])
    assert result.exit_code == 0, result.output
    from dualpixel.inference.onnx_runtime import load_onnx_checkpoint

    assert load_onnx_checkpoint(graph).output_settings == {"brightness": "tied"}
    outputs = {}
    for label, checkpoint, extra in (("torch", tied_checkpoint, []), ("onnx", graph, []),
                                     ("untied", tied_checkpoint, ["--brightness", "model"])):
        out = tmp_path / f"{label}.png"
        result = runner.invoke(cli, ["deblur", "--left", str(tmp_path / "left.png"), "--right",
                                     str(tmp_path / "right.png"), "--checkpoint",
                                     str(checkpoint), "--device", "cpu", "--precision", "fp32",
                                     "-o", str(out), *extra])
        assert result.exit_code == 0, result.output
        outputs[label] = cv2.imread(str(out)).astype(int)
    assert np.abs(outputs["onnx"] - outputs["torch"]).max() <= 1  # within the export's tolerance
    assert np.abs(outputs["untied"] - outputs["torch"]).max() > 2

    import onnx

    older = onnx.load(str(graph))  # as an older version exported it: no settings
    for entry in older.metadata_props:
        if entry.key == "dualpixel":
            import json

            description = json.loads(entry.value)
            description.pop("output")
            entry.value = json.dumps(description)
    onnx.save(older, str(tmp_path / "older.onnx"))
    with pytest.warns(UserWarning, match="older.onnx carries no output settings"):
        assert load_onnx_checkpoint(tmp_path / "older.onnx").output_settings == {}


def test_a_network_built_here_runs_as_the_network_gives_it(pair):
    from dualpixel.models import build_model

    torch.manual_seed(0)
    net = build_model("rdpd", width=0.125).eval()
    assert net.output_settings == {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = deblur(*pair, model=net, device="cpu", precision="fp32")
    assert out.shape == pair[0].shape
