"""The NAF-block levels (dualpixel.models.naf) and the U-Net built of them (model ``dpnaf``)."""

import pytest
import torch
import torch.nn.functional as F

from dualpixel.errors import ParameterError
from dualpixel.models import MODELS, build_architecture, build_model, load_model, save_model
from dualpixel.models.naf import LayerNorm2d, NAFBlock
from dualpixel.models.spec import ModelSpec
from dualpixel.models.unet import DeblurNet, NetworkShape
from dualpixel.training import load_config
from tests.conftest import busy_naf

TINY = 0.125


def busy(model: torch.nn.Module) -> torch.nn.Module:
    return busy_naf(model, std=0.3, seed=0)


def test_layer_norm_equals_torch_on_the_channels_in_both_memory_layouts():
    torch.manual_seed(0)
    norm = LayerNorm2d(6)
    with torch.no_grad():
        norm.weight.normal_()
        norm.bias.normal_()
    x = torch.randn(2, 6, 9, 11) * 3 + 1
    expected = F.layer_norm(x.permute(0, 2, 3, 1), (6,), norm.weight, norm.bias,
                            1e-6).permute(0, 3, 1, 2)
    torch.testing.assert_close(norm(x), expected, rtol=1e-5, atol=1e-5)
    last = norm(x.contiguous(memory_format=torch.channels_last))
    torch.testing.assert_close(last, expected, rtol=1e-5, atol=1e-5)
    assert last.dtype == x.dtype


def test_a_fresh_block_is_the_identity_and_a_trained_one_is_not():
    block = NAFBlock(8).eval()
    x = torch.randn(2, 8, 12, 10)
    torch.testing.assert_close(block(x), x)
    busy(block)
    y = block(x)
    assert y.shape == x.shape and (y - x).abs().mean() > 0.05


def test_a_block_is_local_three_pixels_wide():
    """One 3x3 depthwise convolution: a change at one pixel moves only its 3x3 neighbourhood
    (no global pooling, so tiles equal the whole frame)."""
    block = busy(NAFBlock(4))
    x = torch.randn(1, 4, 15, 15)
    changed = x.clone()
    changed[0, :, 7, 7] += torch.tensor([3.0, -2.0, 1.0, 0.5])  # not a shift LN removes
    with torch.no_grad():
        moved = (block(changed) - block(x)).abs().amax(1)[0] > 1e-6
    assert moved[6:9, 6:9].all() and moved.sum() == 9


def test_block_keeps_its_input_dtype_under_autocast():
    block = busy(NAFBlock(8))
    x = torch.randn(1, 8, 16, 16).contiguous(memory_format=torch.channels_last)
    with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16):
        y = block(x.bfloat16())
    assert y.dtype == torch.bfloat16
    torch.testing.assert_close(y.float(), block(x), rtol=0.05, atol=0.05)


def test_dpnaf_starts_at_the_blurred_input_and_round_trips_through_a_checkpoint(tmp_path):
    model = build_model("dpnaf", width=TINY, residual=True).eval()
    assert model.shape.block == "naf" and not model.recurrent
    x = torch.rand(1, 2, 7, 20, 30)
    with torch.no_grad():
        y, state = model(x)
    assert state is None
    torch.testing.assert_close(y, (x[:, :, :3] + x[:, :, 3:6]) / 2)
    busy(model)
    save_model(tmp_path / "naf.safetensors", model)
    loaded = load_model(tmp_path / "naf.safetensors")
    assert loaded.spec.name == "dpnaf" and loaded.shape.block_counts == MODELS["dpnaf"].block_counts
    with torch.no_grad():
        torch.testing.assert_close(loaded(x)[0], model(x)[0])
        assert (model(x)[0] - (x[:, :, :3] + x[:, :, 3:6]) / 2).abs().mean() > 1e-3


def test_dpnaf_levels_have_the_spec_widths_and_block_counts():
    model = build_architecture("dpnaf-light")
    counts = MODELS["dpnaf"].block_counts
    widths = model.shape.encoder
    assert widths == (16, 32, 64, 128) and model.shape.bottleneck == 256
    blocks = [sum(isinstance(m, NAFBlock) for m in level.modules())
              for level in (*model.encoders, model.bottleneck, *model.decoders)]
    assert tuple(blocks) == counts
    sizes = []
    model.downs[-1].register_forward_hook(lambda m, i, o: sizes.append(o.shape))
    with torch.no_grad():
        model.step(torch.rand(1, 7, 64, 96))
    assert sizes == [torch.Size([1, 256, 4, 6])]  # the bottleneck at 1/16


def test_naf_levels_refuse_what_they_cannot_be():
    spec = MODELS["dpnaf"]
    shape = dict(in_channels=7, encoder=(4, 8), bottleneck=16, recurrent=False, output="clamp",
                 block="naf")
    with pytest.raises(ValueError, match="5 block counts"):
        DeblurNet(NetworkShape(**shape, block_counts=(1, 1, 1)), spec=spec)
    with pytest.raises(ValueError, match="recurrent"):
        DeblurNet(NetworkShape(**{**shape, "recurrent": True}, block_counts=(1,) * 5), spec=spec)
    with pytest.raises(ValueError, match="unknown level block"):
        DeblurNet(NetworkShape(**{**shape, "block": "mlp"}, block_counts=(1,) * 5), spec=spec)
    model = build_model("dpnaf", width=TINY)
    with pytest.raises(ValueError, match="convolution levels"):
        model.reinit_bottleneck()
    for option in ("widen_init", "reinit_bottleneck"):
        with pytest.raises(ParameterError, match=f"{option} is for the paper's"):
            load_config(None, {"model": "dpnaf", "synthetic_data": "x", option: True,
                               "init_weights": "x.safetensors"})


def test_a_spec_without_naf_counts_keeps_the_papers_levels():
    spec = ModelSpec("x", 2, True, True, (4, 8), 16, "clamp", 0.0, "test")
    assert spec.block == "conv" and spec.block_counts == ()
    model = build_model("rdpd", width=TINY)
    assert model.downs is None and model.shape.block == "conv"
