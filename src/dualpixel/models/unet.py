"""The encoder-decoder shared by RDPD and DPDNet (paper Sec. 4, Fig. 6; Abuolaim & Brown 2020).

Encoder: per level two 3x3 conv + ReLU, then 2x2 max-pool. Bottleneck: RDPD has one 3x3 conv and
the ConvLSTM (Eq. 8-12); DPDNet two 3x3 convs and dropout. Decoder: per level 2x upsampling, a 2x2
conv + ReLU (Keras ``padding="same"``: one extra row and column at the bottom and right), skip
concatenation and two 3x3 conv + ReLU. Head: a 3-channel 3x3 conv + ReLU and a 1x1 conv, clamped to
[0, 1] (RDPD, "linear layer with clamping") or through a sigmoid (DPDNet). He-normal initialisation.

Option (ours, off by default): ``residual=True`` adds the blurred input (the mean of the views) to
the head's output before clamping, with the last layer initialised to zero so training starts from
the identity, and drops the ReLU of the 3-channel layer (a correction needs both signs). It adds
no parameters and makes short CPU training converge much faster.

Option (ours, off by default): ``head_relu=False`` drops that ReLU from a non-residual head too
(the 3-channel convolution straight into the 1x1 one): under Adam the ReLU's channels can fall
negative everywhere and stop learning (see :meth:`DeblurNet.centre_head`).

Option (ours, off by default): ``refiner=(w1, w2, ...)`` appends a refiner,
:class:`~dualpixel.models.refiner.Refiner`, that corrects the clamped output from the input and
that output; it starts as the identity, so it can be trained on top of a trained (frozen) network.

Option (ours, off by default): a recurrent spec built with ``recurrent=False`` in its shape
(``build_model(..., conv_bottleneck=True)``) gets DPDNet's bottleneck, two 3x3 convolutions,
in place of its convolution and ConvLSTM: a network without state
(:attr:`DeblurNet.conv_bottleneck`).

Option (ours, per model): ``block="naf"`` builds every level of NAF blocks instead
(:mod:`dualpixel.models.naf`; model ``dpnaf``), with strided convolutions down and pixel-shuffle
up-convolutions; the skips, the residual output and the refiner are as above.

Any input size: the input is reflect-padded to a multiple of 16 and the output cropped back.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from dualpixel.models.convlstm import ConvLSTMCell, LSTMState
from dualpixel.models.naf import ShuffleUp, naf_blocks, naf_down
from dualpixel.models.padding import SIZE_MULTIPLE, pad_to_multiple
from dualpixel.models.refiner import Refiner
from dualpixel.models.spec import ModelSpec

__all__ = ["SIZE_MULTIPLE", "DeblurNet", "NetworkShape", "pad_to_multiple", "pass_memory"]


@dataclass(frozen=True)
class NetworkShape:
    """Layer widths and head of one network (see ``dualpixel.models.registry`` for the presets)."""

    in_channels: int
    encoder: tuple[int, ...]
    bottleneck: int
    recurrent: bool
    output: str  # "clamp" or "sigmoid"
    encoder_dropout: float = 0.0  # after the last encoder level and the bottleneck (DPDNet)
    lstm_dropout: float = 0.4
    peepholes: bool = True
    residual: bool = False  # output = input image + network output (not in the paper)
    # Widths of a refiner that corrects the base output (ours; dualpixel.models.refiner); () none.
    refiner: tuple[int, ...] = ()
    # Levels of two 3x3 convolutions ("conv") or of NAF blocks ("naf", dualpixel.models.naf), and
    # the NAF blocks per encoder level, bottleneck and decoder level.
    block: str = "conv"
    block_counts: tuple[int, ...] = ()
    # The ReLU after the head's 3-channel convolution, where the head has one (the paper's levels
    # without the residual output); False drops it there too (ours).
    head_relu: bool = True


def _conv_relu(cin: int, cout: int, kernel: int = 3) -> list[nn.Module]:
    return [nn.Conv2d(cin, cout, kernel, padding=kernel // 2), nn.ReLU(inplace=True)]


def _double_conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(*_conv_relu(cin, cout), *_conv_relu(cout, cout))


class _UpConv(nn.Module):
    """2x nearest upsampling and a 2x2 conv with Keras "same" padding (pad right and bottom),
    then ReLU; ``(B, cin, H, W)`` -> ``(B, cout, 2H, 2W)``.

    Computed without the upsampled image: output pixel ``(2i + a, 2j + b)`` sees input rows
    ``i + (a + dy) // 2`` and columns ``j + (b + dx) // 2`` for the kernel taps ``(dy, dx)``, so
    each output phase ``(a, b)`` is a 2x2 conv of the input with the taps that land on the same
    input pixel summed (:meth:`phase_weight`). One conv with ``4 cout`` outputs at the input's
    resolution and a pixel shuffle give the same result with the same arithmetic, and none of
    the memory traffic of the 4x upsampled and padded copies.
    """

    def __init__(self, cin: int, cout: int) -> None:
        super().__init__()
        self.conv = nn.Conv2d(cin, cout, 2)

    def phase_weight(self) -> torch.Tensor:
        """``(4 cout, cin, 2, 2)``: the kernel of output phase ``(a, b)`` of channel ``c`` at
        index ``4 c + 2 a + b`` (the order ``pixel_shuffle`` reads)."""
        w = self.conv.weight
        zero = torch.zeros_like(w[:, :, 0, 0])
        w00, w01, w10, w11 = w[:, :, 0, 0], w[:, :, 0, 1], w[:, :, 1, 0], w[:, :, 1, 1]
        phases = [  # per phase: taps at input offsets (0, 0), (0, 1), (1, 0), (1, 1)
            (w00 + w01 + w10 + w11, zero, zero, zero),  # a = 0, b = 0
            (w00 + w10, w01 + w11, zero, zero),  # a = 0, b = 1
            (w00 + w01, zero, w10 + w11, zero),  # a = 1, b = 0
            (w00, w01, w10, w11),  # a = 1, b = 1
        ]
        kernels = torch.stack([torch.stack(taps, -1) for taps in phases], 1)  # (cout, 4, cin, 4)
        return kernels.reshape(-1, w.shape[1], 2, 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        bias = self.conv.bias.repeat_interleave(4) if self.conv.bias is not None else None
        # Padding 1 on every side; the first row and column are the ones Keras does not pad.
        y = F.conv2d(x, self.phase_weight(), bias, padding=1)[:, :, 1:, 1:]
        return F.pixel_shuffle(F.relu(y), 2)


class DeblurNet(nn.Module):
    """U-Net deblurring network, recurrent (ConvLSTM bottleneck) or not.

    ``step`` runs one frame ``(B, C, H, W)`` with an optional recurrent state; ``forward`` runs a
    sequence ``(B, T, C, H, W)`` frame by frame, carrying the state, and returns
    ``(B, T, 3, H, W)`` with the final state (``None`` for a non-recurrent network).
    """

    def __init__(self, shape: NetworkShape, *, spec: ModelSpec, width: float = 1.0) -> None:
        super().__init__()
        self.shape = shape
        self.spec = spec  # the named network this is (dualpixel.models.spec.MODELS)
        self.width = width  # the multiplier of the spec's layer widths
        #: Whether inference carries the ConvLSTM state from frame to frame. False for a model
        #: trained on single frames only (sRDPD+ and real pairs): its state was always zero in
        #: training, so carrying one across frames would feed it inputs it never saw.
        self.temporal = shape.recurrent
        #: How the weights are meant to run (``brightness``, ``overshoot``, ``flips``), carried
        #: from the checkpoint or registry they were loaded from as torchvision's weights carry
        #: their transforms; empty: as the network gives it (``dualpixel.weights.run_settings``).
        self.output_settings: dict[str, object] = {}
        if shape.block == "naf":
            self._build_naf_levels()
        elif shape.block == "conv":
            self._build_conv_levels()
        else:
            raise ValueError(f"unknown level block {shape.block!r}: conv or naf")
        if shape.residual and shape.output != "clamp":
            raise ValueError("a residual network needs the clamped linear output")
        if shape.block == "conv":  # NAF levels keep PyTorch's initialisation, as NAFNet does
            self._init_weights()
        if shape.residual:  # start as the identity: output = blurred input
            nn.init.zeros_(self.head[-1].weight)
            nn.init.zeros_(self.head[-1].bias)
        # Built after the He initialisation: the refiner initialises itself (identity at first).
        self.refiner = Refiner(shape.in_channels, shape.refiner) if shape.refiner else None
        if self.refiner is not None and shape.output != "clamp":
            raise ValueError("a refined network needs the clamped linear output")

    def _build_conv_levels(self) -> None:
        """The paper's levels: two 3x3 conv + ReLU each, max-pooling down (``downs`` None), the
        ConvLSTM or DPDNet's double convolution in the bottleneck, :class:`_UpConv` up."""
        shape = self.shape
        widths = shape.encoder
        self.encoders = nn.ModuleList()
        cin = shape.in_channels
        for width in widths:
            self.encoders.append(_double_conv(cin, width))
            cin = width
        self.downs: nn.ModuleList | None = None
        self.encoder_dropout = nn.Dropout(shape.encoder_dropout)
        if shape.recurrent:
            self.bottleneck = nn.Sequential(*_conv_relu(cin, shape.bottleneck))
            self.lstm: ConvLSTMCell | None = ConvLSTMCell(
                shape.bottleneck,
                shape.bottleneck,
                dropout=shape.lstm_dropout,
                peepholes=shape.peepholes,
            )
        else:
            self.bottleneck = nn.Sequential(
                _double_conv(cin, shape.bottleneck), nn.Dropout(shape.encoder_dropout)
            )
            self.lstm = None
        self.upconvs = nn.ModuleList()
        self.decoders = nn.ModuleList()
        cin = shape.bottleneck
        for width in reversed(widths):
            self.upconvs.append(_UpConv(cin, width))
            self.decoders.append(_double_conv(2 * width, width))
            cin = width
        # The residual variant drops the ReLU of the 3-channel layer: a correction needs both signs.
        head_act = nn.ReLU(inplace=True) if self.head_has_relu else nn.Identity()
        self.head = nn.Sequential(nn.Conv2d(cin, 3, 3, padding=1), head_act, nn.Conv2d(3, 3, 1))

    @property
    def head_has_relu(self) -> bool:
        """Whether the head ends in the paper's 3-channel convolution, ReLU and 1x1 convolution
        (the non-residual networks of the paper's levels unless built with ``head_relu=False``),
        which :meth:`centre_head` serves."""
        shape = self.shape
        return shape.block == "conv" and not shape.residual and shape.head_relu

    def centre_head(self, x: torch.Tensor) -> None:
        """Bias the head's 3-channel convolution so that each of its channels is positive on
        half of the pixels of ``x`` (a training batch's frames ``(B, C_in, H, W)``) before a
        run from nothing (ours; a data-dependent initialisation, Kraehenbuehl et al. 2016).

        He-normal weights reading the last decoder level's non-negative features give each of
        the three channels an offset of random sign larger than its variation, so at zero bias
        a channel is negative almost everywhere about half the time: its ReLU gets no gradient,
        and the output loses that colour direction for good (all three at once for about one
        seed in eight: a network that never learns).
        """
        if not self.head_has_relu:
            raise ValueError("centre_head is for the non-residual head of the paper's levels")
        before_relu = self._seen(x, self.head[0])
        median = before_relu.transpose(0, 1).flatten(1).median(dim=1).values
        with torch.no_grad():
            self.head[0].bias -= median.to(self.head[0].bias)

    def _seen(self, x: torch.Tensor, module: nn.Module, *, its_input: bool = False) -> torch.Tensor:
        """What ``module`` gives (or, ``its_input``, is given) while the network, in evaluation
        mode and without gradients, runs one frame ``x``; float32, detached."""
        seen: list[torch.Tensor] = []
        if its_input:
            hook = module.register_forward_pre_hook(lambda m, args: seen.append(args[0]))
        else:
            hook = module.register_forward_hook(lambda m, args, out: seen.append(out.clone()))
        training = self.training
        self.eval()
        try:
            with torch.no_grad():
                self.step(x)
        finally:
            hook.remove()
            self.train(training)
        return seen[0].detach().float()

    def balance_levels(self, x: torch.Tensor) -> list[float]:
        """Scale each up-convolution, coarsest first, so that on ``x`` (a training batch's
        frames ``(B, C_in, H, W)``) its output has the root mean square of the skip it is
        concatenated with; returns the factors (ours; a data-dependent initialisation after
        LSUV, Mishkin & Matas 2016). A ReLU commutes with a positive scale, so each factor is
        exact. He-normal weights keep the scale of ReLU features from level to level, but the
        ConvLSTM's output is gated and squashed (``o * tanh(c)``, ``|h| < 1``): at He
        initialisation it is about a third of what a convolution there gives, and the finest
        skip decides the first output almost alone. (Measured on Table 2's crops, balancing
        does not bring the light RDPD's idle coarse levels in: ``docs/video.md``.) A level whose
        output is zero on ``x`` keeps its weights.
        """
        if self.shape.block != "conv":
            raise ValueError("balance_levels is for the paper's convolution levels")
        factors = []
        for upconv, decoder in zip(self.upconvs, self.decoders):
            joined = self._seen(x, decoder, its_input=True)  # [skip, upconv(x)]
            skip, up = joined.chunk(2, dim=1)
            up_rms = float(up.square().mean().sqrt())
            factor = float(skip.square().mean().sqrt()) / up_rms if up_rms > 0 else 1.0
            with torch.no_grad():
                upconv.conv.weight *= factor
                if upconv.conv.bias is not None:
                    upconv.conv.bias *= factor
            factors.append(factor)
        return factors

    def _build_naf_levels(self) -> None:
        """NAF levels (:mod:`dualpixel.models.naf`): a 3x3 convolution into the first, NAF blocks
        at every level, a 2x2 stride-2 convolution down (the next level's width), the skip and
        the upsampled features joined by a 1x1 convolution, a 3x3 convolution to the image."""
        shape = self.shape
        widths, depth = shape.encoder, len(shape.encoder)
        counts = shape.block_counts
        if len(counts) != 2 * depth + 1:
            raise ValueError(f"NAF levels need {2 * depth + 1} block counts (encoder, bottleneck, "
                             f"decoder), got {counts}")
        if shape.recurrent:
            raise ValueError("NAF levels have no recurrent bottleneck")
        self.encoders = nn.ModuleList(
            [naf_blocks(widths[0], counts[0], cin=shape.in_channels, kernel=3)]
            + [naf_blocks(width, count) for width, count in zip(widths[1:], counts[1:depth])])
        self.downs = nn.ModuleList(
            naf_down(cin, cout) for cin, cout in zip(widths, (*widths[1:], shape.bottleneck)))
        self.encoder_dropout = nn.Dropout(shape.encoder_dropout)
        self.bottleneck = naf_blocks(shape.bottleneck, counts[depth])
        self.lstm = None
        self.upconvs = nn.ModuleList()
        self.decoders = nn.ModuleList()
        cin = shape.bottleneck
        for width, count in zip(reversed(widths), counts[depth + 1:]):
            self.upconvs.append(ShuffleUp(cin, width))
            self.decoders.append(naf_blocks(width, count, cin=2 * width))
            cin = width
        self.head = nn.Sequential(nn.Conv2d(cin, 3, 3, padding=1))

    def _init_weights(self) -> None:
        for module in self.modules():
            lstm_input = getattr(self.lstm, "input_conv", None)
            if isinstance(module, nn.Conv2d) and module is not lstm_input:
                nn.init.kaiming_normal_(module.weight, nonlinearity="relu")
                if module.bias is not None:
                    nn.init.zeros_(module.bias)
        if self.lstm is not None:
            nn.init.kaiming_normal_(self.lstm.input_conv.weight, nonlinearity="relu")

    def reinit_bottleneck(self) -> None:
        """Give the base network's coarsest level fresh weights without changing what the network
        computes from it onwards (ours, after ReDo, Sokar et al. 2023, "The Dormant Neuron
        Phenomenon").

        The bottleneck (conv, ConvLSTM; DPDNet: its two convs) and the first up-convolution get
        new He-normal weights from the global torch RNG, and the first decoder convolution's
        weights on the up-convolution's half of its input are zeroed. The output then no longer
        depends on the coarsest level at all (in our trained models that level had gone dormant:
        its ReLUs almost never fire, and zeroing it changed the training MSE by < 1 %), and
        training can bring the revived units back in: their activations are alive, so the zeroed
        weights get gradients. For the paper's levels only: NAF blocks have no ReLU to die.
        """
        if self.shape.block != "conv":
            raise ValueError("reinit_bottleneck is for the paper's convolution levels (NAF "
                             "blocks have no ReLU that could go dormant)")
        fresh = DeblurNet(self.shape, spec=self.spec, width=self.width)
        with torch.no_grad():
            for mine, new in zip(self.coarsest_level(), fresh.coarsest_level(), strict=True):
                mine.load_state_dict(new.state_dict())
            first = self.decoders[0][0]
            first.weight[:, self.shape.encoder[-1]:].zero_()  # input: [skip, upconv(x)]

    def base_parameters(self) -> list[nn.Parameter]:
        """Every parameter but the refiner's (all of them for a network without one)."""
        return [p for name, p in self.named_parameters() if not name.startswith("refiner.")]

    def coarsest_level(self) -> list[nn.Module]:
        """The modules working at 1/16 of the input size: the bottleneck (and ConvLSTM; with NAF
        levels the convolution down into it) and the first up-convolution, which brings their
        output back to 1/8."""
        modules: list[nn.Module] = [self.bottleneck]
        if self.downs is not None:
            modules.insert(0, self.downs[-1])
        if self.lstm is not None:
            modules.append(self.lstm)
        return [*modules, self.upconvs[0]]

    @property
    def recurrent(self) -> bool:
        return self.lstm is not None

    @property
    def conv_bottleneck(self) -> bool:
        """Whether a network the paper builds with a ConvLSTM has DPDNet's two convolutions in
        its place (``build_model(..., conv_bottleneck=True)``)."""
        return self.spec.recurrent and not self.shape.recurrent

    def step(
        self, x: torch.Tensor, state: LSTMState | None = None
    ) -> tuple[torch.Tensor, LSTMState | None]:
        """Deblur one frame ``(B, C_in, H, W)``; returns ``(B, 3, H, W)`` and the next state."""
        if x.ndim != 4 or x.shape[1] != self.shape.in_channels:
            raise ValueError(
                f"expected input (B, {self.shape.in_channels}, H, W), got {tuple(x.shape)}"
            )
        # The blurred image the residual is added to: the mean of the views (first 3 or 6 channels).
        base = x[:, :3] if self.shape.in_channels in (3, 4) else (x[:, :3] + x[:, 3:6]) / 2
        inputs = x
        x, height, width = pad_to_multiple(x)
        skips = []
        for index, encoder in enumerate(self.encoders):
            x = encoder(x)
            if index == len(self.encoders) - 1:
                x = self.encoder_dropout(x)
            skips.append(x)
            x = F.max_pool2d(x, 2) if self.downs is None else self.downs[index](x)
        x = self.bottleneck(x)
        if self.lstm is not None:
            state = self.lstm(x, state)
            x = state[0]
        for upconv, decoder, skip in zip(self.upconvs, self.decoders, reversed(skips)):
            x = decoder(torch.cat([skip, upconv(x)], dim=1))
        x = self.head(x)[..., :height, :width]
        if self.shape.residual:
            x = x + base
        x = x.clamp(0.0, 1.0) if self.shape.output == "clamp" else torch.sigmoid(x)
        if self.refiner is not None:
            x = self.refiner(inputs, x)
        return x, state if self.lstm is not None else None

    def forward(
        self, frames: torch.Tensor, state: LSTMState | None = None
    ) -> tuple[torch.Tensor, LSTMState | None]:
        """Deblur a sequence ``(B, T, C_in, H, W)`` frame by frame, carrying the ConvLSTM state."""
        if frames.ndim != 5:
            raise ValueError(f"expected frames (B, T, C, H, W), got {tuple(frames.shape)}")
        batch, length = frames.shape[:2]
        if self.lstm is None:  # no state: all frames at once
            out, _ = self.step(frames.flatten(0, 1))
            return out.unflatten(0, (batch, length)), None
        outputs = []
        for t in range(length):
            out, state = self.step(frames[:, t], state)
            outputs.append(out)
        return torch.stack(outputs, dim=1), state


def pass_memory(model: DeblurNet, pixels: int) -> int:
    """Bytes one network pass over ``pixels`` (members x height x width) takes at its peak, in
    float32, with margin: 20 bytes per channel of the first encoder and refiner level (72 for a
    NAF level, whose blocks hold twice its channels and their norms), plus 128 for the frame's
    input and output. Measured peaks on the CPU: the default model (16 + 32 channels) 650-800
    bytes a pixel at 1620x980 and 840x512, estimated 1088; rdpd-wide (32 + 32) 1230, estimated
    1408; dpnaf-light (16, NAF) 935-1222, estimated 1280.

    >>> from dualpixel.models.registry import build_model
    >>> pass_memory(build_model("rdpd", width=0.5, refiner=(32, 64, 128)), 1000)
    1088000
    """
    shape = model.shape
    per_channel = 72 if shape.block == "naf" else 20
    refiner = 20 * shape.refiner[0] if shape.refiner else 0
    return (per_channel * shape.encoder[0] + refiner + 128) * pixels
