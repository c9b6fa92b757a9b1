import pytest
import torch

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.models import build_model, load_model, load_weights, save_model
from dualpixel.models.refiner import Refiner

TINY = 0.125


def test_a_fresh_refiner_is_the_identity_on_the_base():
    torch.manual_seed(0)
    plain = build_model("rdpd", width=TINY, residual=True).eval()
    refined = build_model("rdpd", width=TINY, residual=True, refiner=(8, 16)).eval()
    refined.load_state_dict({**refined.state_dict(), **plain.state_dict()})
    x = torch.rand(2, 1, 7, 37, 50)  # not a multiple of 8: padded and cropped back
    with torch.no_grad():
        torch.testing.assert_close(refined(x)[0], plain(x)[0])
    assert len(refined.base_parameters()) == len(list(plain.parameters()))


def test_refiner_corrects_with_a_large_receptive_field_and_keeps_the_range():
    torch.manual_seed(1)
    refiner = Refiner(7, (8, 16, 16))
    torch.nn.init.normal_(refiner.head.weight, std=0.5)
    x, first = torch.rand(1, 7, 64, 64), torch.rand(1, 3, 64, 64)
    out = refiner(x, first)
    assert out.shape == first.shape and 0 <= out.min() and out.max() <= 1
    assert not torch.allclose(out, first)
    # A change at one corner reaches far across the frame (half resolution, three poolings).
    moved = x.clone()
    moved[..., :4, :4] += 1
    changed = (refiner(moved, first) - out).abs().amax(dim=(0, 1))
    assert changed[40:, 40:].max() > 0
    with pytest.raises(ValueError, match=r"expected input \(B, 7, H, W\)"):
        refiner(torch.rand(1, 6, 16, 16), torch.rand(1, 3, 16, 16))
    with pytest.raises(ValueError, match="positive channel counts"):
        Refiner(7, ())


def test_refined_checkpoints_round_trip_and_load_a_base(tmp_path):
    torch.manual_seed(2)
    refined = build_model("rdpd", width=TINY, residual=True, refiner=(8, 16)).eval()
    torch.nn.init.normal_(refined.refiner.head.weight, std=0.1)
    save_model(tmp_path / "refined.safetensors", refined)
    loaded = load_model(tmp_path / "refined.safetensors")
    assert loaded.shape.refiner == (8, 16)
    x = torch.rand(1, 1, 7, 32, 32)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x)[0], refined(x)[0])
    # A network without a refiner loads only as the base network, and only when asked to.
    plain = build_model("rdpd", width=TINY, residual=True)
    save_model(tmp_path / "plain.safetensors", plain)
    with pytest.raises(InputFileError, match="checkpoint is for"):
        load_weights(refined, tmp_path / "plain.safetensors")
    head = refined.refiner.head.weight.clone()
    load_weights(refined, tmp_path / "plain.safetensors", base_only=True)
    torch.testing.assert_close(refined.encoders[0][0].weight, plain.encoders[0][0].weight)
    torch.testing.assert_close(refined.refiner.head.weight, head)
    with pytest.raises(InputFileError, match="checkpoint is for"):
        load_weights(plain, tmp_path / "refined.safetensors")
    with pytest.raises(ParameterError, match="sigmoid"):
        build_model("dpdnet", width=TINY, refiner=(8,))
