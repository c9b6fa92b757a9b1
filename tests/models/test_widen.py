import pytest
import torch

from dualpixel.errors import ParameterError
from dualpixel.models import build_model
from dualpixel.models.widen import widen_network, widening_factor


def _trained_like(name, **options):
    """A narrow network with every weight moved off its initialisation (the residual head's
    last layer starts at zero)."""
    torch.manual_seed(0)
    net = build_model(name, width=0.125, **options).eval()
    with torch.no_grad():
        for parameter in net.parameters():
            parameter.add_(0.05 * torch.randn_like(parameter))
    return net


@pytest.mark.parametrize(("name", "options"), [
    ("rdpd", {"residual": True, "refiner": (8, 16)}), ("dpdnet", {})])
@pytest.mark.parametrize("k", [2, 3])
def test_widened_network_computes_the_narrow_ones_function(name, options, k):
    small = _trained_like(name, **options)
    big = build_model(name, width=0.125 * k, **options).eval()
    assert widening_factor(small, big) == k
    widen_network(small, big)
    torch.manual_seed(1)
    frames = torch.rand(1, 2, small.shape.in_channels, 48, 64)  # two frames: the state carried
    with torch.no_grad():
        expected, _ = small(frames)
        got, _ = big(frames)
    torch.testing.assert_close(got, expected, rtol=0, atol=2e-5)
    with torch.no_grad():  # and the network is not just passing its input through
        untrained, _ = build_model(name, width=0.125 * k, **options).eval()(frames)
    assert (untrained - expected).abs().max() > 0.05


def test_copies_read_with_uneven_weights_that_sum_to_the_trained_one():
    small = _trained_like("rdpd", residual=True)
    big = build_model("rdpd", width=0.25, residual=True)
    widen_network(small, big, noise=0.1)
    width = small.shape.encoder[0]
    narrow = small.encoders[0][2].weight  # reads level 0's first convolution
    wide = big.encoders[0][2].weight  # (2 width, 2 width, 3, 3): copies j and j + width
    torch.testing.assert_close(wide[:width, :width] + wide[:width, width:], narrow)
    torch.testing.assert_close(wide[width:, :width] + wide[width:, width:], narrow)
    assert (wide[:width, :width] - wide[:width, width:]).abs().max() > 1e-3  # not split evenly
    widen_network(small, big, noise=0.0)
    torch.testing.assert_close(big.encoders[0][2].weight[:, :width], narrow.repeat(2, 1, 1, 1) / 2)


def test_widening_refuses_what_is_not_a_wider_copy():
    small = build_model("rdpd", width=0.25)
    with pytest.raises(ParameterError, match="not one integer multiple"):
        widen_network(small, build_model("rdpd", width=0.375))
    with pytest.raises(ParameterError, match="differ in more than width"):
        widen_network(small, build_model("dpdnet", width=0.5))
    with pytest.raises(ParameterError, match="residual"):
        widen_network(small, build_model("rdpd", width=0.5, residual=True))
    with pytest.raises(ParameterError, match="refiner"):
        widen_network(build_model("rdpd", width=0.25, residual=True, refiner=(8,)),
                      build_model("rdpd", width=0.5, residual=True, refiner=(16,)))
