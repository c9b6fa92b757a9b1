"""Issue #36: the precision the default path picks, its refusals, and its fidelity."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import ParameterError
from dualpixel.evaluation.metrics import psnr
from dualpixel.inference import Deblurrer, precision
from dualpixel.io.images import read_rgb
from dualpixel.weights import resolve_checkpoint


@pytest.fixture
def native_bf16(monkeypatch):
    def set_native(value: bool) -> None:
        monkeypatch.setattr(precision, "cpu_has_native_bf16", lambda: value)
    return set_native


def test_auto_takes_bf16_only_where_the_cpu_computes_it(native_bf16):
    native_bf16(True)
    chosen = precision.resolve_precision("auto", "cpu")
    assert chosen.dtype == torch.bfloat16 and chosen.channels_last
    native_bf16(False)
    assert precision.resolve_precision("auto", "cpu").dtype is None  # plain float32
    with pytest.raises(ParameterError, match=r"no native bfloat16.*use fp32 or auto"):
        precision.resolve_precision("bf16", "cpu")
    with pytest.raises(ParameterError, match="fp16 runs on CUDA only"):
        precision.resolve_precision("fp16", "cpu")
    with pytest.raises(ParameterError, match="precision must be one of"):
        precision.resolve_precision("int8", "cpu")


def test_the_cli_names_the_fallback(native_bf16, tmp_path):
    native_bf16(False)
    view = tmp_path / "v.png"
    from PIL import Image
    other = tmp_path / "w.png"
    for path in (view, other):
        Image.fromarray(np.full((32, 32, 3), 100, np.uint8)).save(path)
    result = CliRunner().invoke(cli, ["deblur", "--left", str(view), "--right", str(other), "-o",
                                      str(tmp_path / "o.png"), "--precision", "bf16"])
    assert result.exit_code == 2 and "no native bfloat16" in result.output, result.output
    result = CliRunner().invoke(cli, ["deblur", "--left", str(view), "--right", str(other), "-o",
                                      str(tmp_path / "o.png"), "--precision", "auto"])
    assert result.exit_code == 0, result.output


@pytest.mark.skipif(not precision.cpu_has_native_bf16(), reason="this CPU has no native bf16")
def test_bf16_stays_within_002_db_of_fp32_on_a_canon_crop(shared_dir):
    from dualpixel.models import load_model

    folder = shared_dir / "data" / "canon-dp-real-hd" / "scene_04"
    left, right, target = (read_rgb(folder / f"{name}.png")[200:456, 400:784]
                           for name in ("view0", "view1", "target"))
    model = load_model(resolve_checkpoint("rdpd-light"))
    scores = {name: psnr(Deblurrer(model, precision=name)(left, right), target)
              for name in ("fp32", "bf16")}
    assert scores["fp32"] > psnr((left + right) / 2, target)  # the model works on the crop
    assert abs(scores["bf16"] - scores["fp32"]) <= 0.02, scores
