import pytest
import torch

from dualpixel.errors import InputFileError, ParameterError
from dualpixel.models import (
    MODELS,
    ConvLSTMCell,
    build_model,
    count_parameters,
    load_model,
    save_model,
)

TINY = 0.125


def test_parameter_counts_match_the_published_models():
    # The authors' Keras RDPD (ConvLSTM2D has no peepholes) and DPDNet (ECCV 2020).
    assert count_parameters(build_model("rdpd", peepholes=False)) == 24_278_703
    assert count_parameters(build_model("dpdnet")) == 31_035_151
    # Peepholes add one weight per channel for three gates.
    assert count_parameters(build_model("rdpd")) == 24_278_703 + 3 * 512


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("size", [(37, 53), (16, 16), (21, 8)])
def test_output_has_the_input_size(name, size):
    model = build_model(name, width=TINY).eval()
    spec = MODELS[name]
    x = torch.rand(2, 3, spec.in_channels, *size)
    with torch.no_grad():
        y, state = model(x)
    assert y.shape == (2, 3, 3, *size)
    assert y.min() >= 0 and y.max() <= 1
    assert (state is not None) == spec.recurrent


def test_recurrent_model_is_causal_and_carries_state():
    torch.manual_seed(0)
    model = build_model("rdpd", width=TINY).eval()
    for p in model.lstm.parameters():  # make the recurrence matter
        p.data.normal_(0, 0.3)
    seq = torch.rand(1, 3, 7, 24, 40)
    with torch.no_grad():
        full, final = model(seq)
        first, _ = model(seq[:, :1])
        # One frame alone equals the first frame of the longer sequence.
        torch.testing.assert_close(first[:, 0], full[:, 0])
        # Frame by frame with the carried state equals the whole sequence.
        state = None
        for t in range(3):
            out, state = model.step(seq[:, t], state)
            torch.testing.assert_close(out, full[:, t])
        torch.testing.assert_close(state[0], final[0])
        # Without the state the later frames differ: the state is used.
        fresh, _ = model.step(seq[:, 2], None)
    assert (fresh - full[:, 2]).abs().max() > 1e-4


def test_convlstm_peepholes_switch():
    with_p = ConvLSTMCell(4, 6, peepholes=True)
    without = ConvLSTMCell(4, 6, peepholes=False)
    assert count_parameters(with_p) - count_parameters(without) == 3 * 6
    # Keras ConvLSTM2D: 4 * (k*k*(cin + cout)*cout + cout)
    assert count_parameters(without) == 4 * (9 * (4 + 6) * 6 + 6)


def test_convlstm_without_state_equals_an_explicit_zero_state():
    # The first frame skips the recurrent convolution; it must equal Eq. 8-12 with H = C = 0.
    torch.manual_seed(0)
    cell = ConvLSTMCell(4, 6, dropout=0.0).eval()
    with torch.no_grad():
        cell.peephole.normal_()  # non-zero peepholes: the skipped terms must truly vanish
        cell.recurrent_conv.weight.normal_()
        x = torch.randn(2, 4, 9, 11)
        fast = cell(x, None)
        full = cell(x, cell.initial_state(x))
    for a, b in zip(fast, full):
        torch.testing.assert_close(a, b)


def test_dropout_only_in_training():
    model = build_model("rdpd", width=TINY)
    x = torch.rand(1, 1, 7, 16, 16)
    model.eval()
    with torch.no_grad():
        a, _ = model(x)
        b, _ = model(x)
    torch.testing.assert_close(a, b)


def test_unknown_model_and_bad_width():
    with pytest.raises(ParameterError, match="unknown model"):
        build_model("unet3000")
    with pytest.raises(ParameterError, match="width"):
        build_model("rdpd", width=0)


def test_checkpoint_round_trip_and_refusals(tmp_path):
    torch.manual_seed(0)  # random weights and input: the float16 error below is then fixed
    model = build_model("rdpd", width=0.3).eval()
    path = tmp_path / "m.safetensors"
    save_model(path, model, extra={"note": "x"})
    loaded = load_model(path)
    x = torch.rand(1, 1, 7, 32, 32)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x)[0], model(x)[0])
    # Half precision storage loads as float32 and stays close.
    half = tmp_path / "half.safetensors"
    save_model(half, model, dtype=torch.float16)
    with torch.no_grad():
        assert (load_model(half)(x)[0] - model(x)[0]).abs().max() < 1e-2
    assert next(load_model(half).parameters()).dtype == torch.float32

    from dualpixel.models import load_weights

    other = build_model("dpdnet", width=TINY)
    with pytest.raises(InputFileError, match="checkpoint is for"):
        load_weights(other, path)
    with pytest.raises(InputFileError, match="not found"):
        load_model(tmp_path / "missing.safetensors")
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(InputFileError, match=r"bad\.safetensors"):
        load_model(bad)


def test_residual_option_starts_at_the_blurred_input(tmp_path):
    model = build_model("rdpd", width=TINY, residual=True).eval()
    x = torch.rand(1, 2, 7, 20, 30)
    with torch.no_grad():
        y, _ = model(x)
    torch.testing.assert_close(y, (x[:, :, :3] + x[:, :, 3:6]) / 2)
    save_model(tmp_path / "r.safetensors", model)
    assert load_model(tmp_path / "r.safetensors").shape.residual
    with pytest.raises(ParameterError, match="sigmoid"):
        build_model("dpdnet", residual=True)


def test_a_head_without_its_relu_travels_with_its_checkpoint(tmp_path):
    """``head_relu=False`` builds DPDNet's head as 3x3 conv straight into the 1x1 conv; the file
    says so, so it reloads as built and no other head takes its weights. Files written before
    the key existed load with the ReLU they were trained with."""
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    from dualpixel.models import load_weights

    torch.manual_seed(0)
    linear = build_model("dpdnet", width=TINY, head_relu=False).eval()
    assert not linear.head_has_relu and isinstance(linear.head[1], torch.nn.Identity)
    path = tmp_path / "linear.safetensors"
    save_model(path, linear)
    loaded = load_model(path)
    assert isinstance(loaded.head[1], torch.nn.Identity)
    x = torch.rand(1, 1, 6, 32, 32)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x)[0], linear(x)[0])
    # The same weights with the ReLU give another output: a mixed-up head would not pass unseen.
    with torch.no_grad():
        relu = build_model("dpdnet", width=TINY).eval()
        relu.load_state_dict(linear.state_dict())
        assert (relu(x)[0] - linear(x)[0]).abs().max() > 1e-3
    with pytest.raises(InputFileError, match="checkpoint is for"):
        load_weights(relu, path)

    old = tmp_path / "old.safetensors"
    save_model(old, relu)
    with safe_open(str(old), framework="pt") as handle:
        metadata = {k: v for k, v in handle.metadata().items() if k != "head_relu"}
    save_file(load_file(str(old)), str(old), metadata=metadata)
    assert load_model(old).head_has_relu

    for options in ({"name": "rdpd", "residual": True}, {"name": "dpnaf", "residual": True},
                    {"name": "dpnaf"}):
        with pytest.raises(ParameterError, match="no ReLU to drop"):
            build_model(**options, width=TINY, head_relu=False)


def test_a_conv_bottleneck_replaces_the_convlstm_and_travels_with_its_checkpoint(tmp_path):
    """``conv_bottleneck=True`` gives RDPD DPDNet's two 3x3 convolutions where its convolution
    and ConvLSTM were: no state, no frame-to-frame dependence, the same parameters as the
    paper's DPDNet bottleneck at that width. The file says so and reloads as built; the
    ConvLSTM network refuses its weights, and networks without a ConvLSTM refuse the option."""
    from dualpixel.models import load_weights

    torch.manual_seed(0)
    net = build_model("rdpd", width=TINY, residual=True, refiner=(4,),
                      conv_bottleneck=True).eval()
    assert net.conv_bottleneck and not net.recurrent and not net.temporal
    dpdnet = build_model("dpdnet", width=TINY / 2)  # its widths are twice RDPD's
    assert count_parameters(net.bottleneck) == count_parameters(dpdnet.bottleneck)
    frames = torch.rand(1, 3, 7, 32, 32)
    with torch.no_grad():
        out, state = net(frames)
        alone, _ = net(frames[:, 2:])  # no state: a frame's output is its own
    assert state is None
    torch.testing.assert_close(out[:, 2:], alone)

    path = tmp_path / "conv.safetensors"
    save_model(path, net)
    loaded = load_model(path)
    assert loaded.conv_bottleneck and not loaded.temporal
    with torch.no_grad():
        torch.testing.assert_close(loaded(frames)[0], out)
    lstm = build_model("rdpd", width=TINY, residual=True, refiner=(4,))
    assert not lstm.conv_bottleneck
    with pytest.raises(InputFileError, match="checkpoint is for"):
        load_weights(lstm, path)
    for name in ("dpdnet", "dpnaf"):
        with pytest.raises(ParameterError, match="no ConvLSTM to replace"):
            build_model(name, width=TINY, conv_bottleneck=True)
    # DPDNet's dropout after the last encoder level and in the bottleneck, given or taken away
    def rates(model):
        return [m.p for m in model.modules() if isinstance(m, torch.nn.Dropout)]

    assert rates(build_model("rdpd", width=TINY, conv_bottleneck=True,
                             encoder_dropout=0.4)) == [0.4, 0.4]
    assert rates(build_model("dpdnet", width=TINY)) == [0.4, 0.4]
    assert rates(build_model("dpdnet", width=TINY, encoder_dropout=0.0)) == [0.0, 0.0]


def _demo_views(size: int = 192) -> torch.Tensor:
    """The shipped demo scene's two views, a centre crop, ``(1, 6, size, size)`` in [0, 1]."""
    from dualpixel.demo import real_scene_dir
    from dualpixel.io.images import read_rgb

    views = [read_rgb(real_scene_dir() / f"view{i}.png") for i in (0, 1)]
    h, w = views[0].shape[:2]
    y, x = (h - size) // 2, (w - size) // 2
    crops = [torch.from_numpy(v[y:y + size, x:x + size].copy()).permute(2, 0, 1) for v in views]
    return torch.cat(crops)[None].float()


def _head_share(model, x: torch.Tensor) -> list[float]:
    """Per channel of the head's 3-channel convolution, the share of pixels where it is > 0."""
    seen = []
    hook = model.head[0].register_forward_hook(lambda m, a, out: seen.append(out.clone()))
    with torch.no_grad():
        model.eval().step(x)
    hook.remove()
    return [float((seen[0][:, c] > 0).float().mean()) for c in range(3)]


@pytest.mark.parametrize("name", ["dpdnet", "rdpd"])
def test_centring_the_head_keeps_its_relu_alive_on_other_crops(name):
    """At zero bias some seed starts with a head channel dead on a real DP crop (DPDNet seed 0:
    all three); centred on one crop of the demo scene, every channel lives on another."""
    views = _demo_views(384)
    one, other = views[..., :192, :192], views[..., 192:, 192:]
    radial = [torch.rand(1, 1, 192, 192)] if build_model(name).shape.in_channels == 7 else []
    shares, centred = [], []
    for seed in range(8):
        torch.manual_seed(seed)
        model = build_model(name, width=0.25)
        shares.append(min(_head_share(model, torch.cat([other, *radial], 1))))
        model.centre_head(torch.cat([one, *radial], 1))
        centred.append(min(_head_share(model, torch.cat([other, *radial], 1))))
    assert min(shares) < 0.05 and min(centred) > 0.1, (shares, centred)
    with pytest.raises(ValueError, match="non-residual"):
        build_model("rdpd", width=TINY, residual=True).centre_head(torch.rand(1, 7, 32, 32))


@pytest.mark.parametrize("name", ["rdpd", "dpdnet"])
def test_reinit_bottleneck_keeps_the_output_and_revives_the_level(name):
    """Fresh coarsest level, output as if that level's path were cut, and the cut gets gradients."""
    torch.manual_seed(0)
    model = build_model(name, width=TINY, lstm_dropout=0.0).eval()
    x = torch.rand(2, 1, MODELS[name].in_channels, 32, 48)
    half = model.shape.encoder[-1]
    cut = build_model(name, width=TINY, lstm_dropout=0.0).eval()
    cut.load_state_dict(model.state_dict())
    with torch.no_grad():
        cut.decoders[0][0].weight[:, half:] = 0
        expected, _ = cut(x)
        # Silence the trained level (as if its ReLUs had died): the revived one must be alive.
        if name == "rdpd":
            model.bottleneck[0].bias.fill_(-1e3)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    model.reinit_bottleneck()
    after = model.state_dict()
    changed = {k for k in after if not torch.equal(before[k], after[k])}
    assert changed >= {k for k in after if k.startswith(("bottleneck.", "upconvs.0."))
                       and k.endswith("weight")}  # (biases start at zero either way)
    assert not any(k.startswith(("encoders.", "upconvs.1.", "decoders.1.", "head.")) for k in
                   changed)
    output, _ = model(x)
    torch.testing.assert_close(output.detach(), expected, rtol=0, atol=1e-6)
    captured = {}
    model.upconvs[0].register_forward_hook(lambda m, i, o: captured.update(up=o))
    output, _ = model(x)
    assert (captured["up"] > 0).float().mean() > 0.2  # alive: ReLUs fire
    output.mean().backward()
    gradient = model.decoders[0][0].weight.grad[:, half:]
    assert gradient.abs().sum() > 0


@pytest.mark.parametrize("name", ["rdpd", "dpdnet"])
def test_balance_levels_gives_each_up_convolution_its_skips_scale(name):
    """After ``balance_levels`` on a batch, every up-convolution's output has the root mean
    square of the skip it joins on that batch; the ConvLSTM's gated output starts well below a
    convolution's, so RDPD's coarsest factor is the largest. NAF levels are refused."""
    torch.manual_seed(0)
    model = build_model(name, width=0.25)
    x = torch.rand(2, MODELS[name].in_channels, 64, 64)
    factors = model.balance_levels(x)
    joined = []
    hooks = [decoder.register_forward_pre_hook(lambda m, args: joined.append(args[0]))
             for decoder in model.decoders]
    with torch.no_grad():
        model.eval().step(x)
    for hook in hooks:
        hook.remove()
    for level, tensor in enumerate(joined):
        half = tensor.shape[1] // 2
        skip, up = tensor[:, :half].square().mean().sqrt(), tensor[:, half:].square().mean().sqrt()
        assert float(up / skip) == pytest.approx(1.0, rel=1e-3), (level, factors)
    if name == "rdpd":
        assert factors[0] == max(factors) and factors[0] > 2, factors
    with pytest.raises(ValueError, match="convolution levels"):
        build_model("dpnaf", width=TINY).balance_levels(torch.rand(1, 7, 32, 32))


def test_up_convolution_equals_upsampling_then_keras_same_conv():
    """The decoder's up-convolution is computed at the input's resolution (phase kernels and a
    pixel shuffle); it must equal its definition, nearest 2x upsampling, one zero row and column
    at the bottom and right, a 2x2 conv and ReLU, in value and in gradient."""
    import torch.nn.functional as F

    from dualpixel.models.unet import _UpConv

    torch.manual_seed(0)
    layer = _UpConv(6, 5)
    x = torch.randn(2, 6, 7, 9, requires_grad=True)
    reference = F.relu(layer.conv(F.pad(F.interpolate(x, scale_factor=2.0, mode="nearest"),
                                        (0, 1, 0, 1))))
    out = layer(x)
    assert out.shape == reference.shape == (2, 5, 14, 18)
    torch.testing.assert_close(out, reference, atol=1e-5, rtol=0)
    weights = torch.randn_like(out)
    grads = torch.autograd.grad((out * weights).sum(), [x, layer.conv.weight, layer.conv.bias])
    grads_ref = torch.autograd.grad((reference * weights).sum(),
                                    [x, layer.conv.weight, layer.conv.bias])
    for got, expected in zip(grads, grads_ref):
        torch.testing.assert_close(got, expected, atol=1e-4, rtol=1e-5)


def test_equal_weights_make_equal_files(tmp_path):
    """The header's metadata comes in one order: saving the same weights again (as two identical
    training runs do) gives the same bytes, and the file loads."""
    import hashlib

    from dualpixel.models import build_model, load_model, read_metadata, save_model

    torch.manual_seed(0)
    model = build_model("rdpd", width=0.125)
    digests = set()
    for k in range(6):
        path = tmp_path / f"m{k}.safetensors"
        save_model(path, model, extra={"b": 1, "a": {"y": 2, "x": 3}, "phase": "p"})
        digests.add(hashlib.sha256(path.read_bytes()).hexdigest())
    assert len(digests) == 1
    assert read_metadata(path)["extra"]["a"] == {"x": 3, "y": 2}
    loaded = load_model(path)
    for key, value in model.state_dict().items():
        assert torch.equal(loaded.state_dict()[key], value)


@pytest.mark.parametrize("key, text, problem", [
    ("peepholes", '"yes"', "peepholes must be JSON bool"),
    ("residual", "1", "residual must be JSON bool"),
    ("refiner", "[8, true]", "refiner must list integer widths"),
    ("refiner", '{"a": 1}', "refiner must be JSON list"),
    ("extra", "[1, 2]", "extra must be JSON dict"),
    ("temporal", "null", "temporal must be JSON bool"),
    ("head_relu", "0", "head_relu must be JSON bool"),
    ("width", "nan", "width must be finite"),
    ("width", "1e999", "width must be finite"),
    ("peepholes", "{", "Expecting property name"),
])
def test_checkpoint_metadata_of_the_wrong_json_type_is_refused(tmp_path, key, text, problem):
    """Issue #72: each header value is JSON of one type; another type (or no JSON) is a clear
    error naming the file and the key, before any network is built."""
    from safetensors.torch import load_file, save_file

    from dualpixel.errors import InputFileError
    from dualpixel.models import build_model, load_model, save_model
    from dualpixel.models.checkpoint import read_metadata

    path = tmp_path / "m.safetensors"
    save_model(path, build_model("rdpd", width=0.125))
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as handle:
        metadata = dict(handle.metadata())
    metadata[key] = text
    save_file(load_file(str(path)), str(path), metadata=metadata)
    with pytest.raises(InputFileError, match=rf"m\.safetensors: checkpoint metadata is "
                                             rf"malformed \(.*{problem}"):
        read_metadata(path)
    with pytest.raises(InputFileError, match=r"m\.safetensors"):
        load_model(path)
