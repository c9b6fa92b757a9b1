"""Convolutional LSTM with peephole connections (paper Sec. 4, Eq. 8-12).

Gates (``*`` convolution, ``o`` element-wise product)::

    i_t = sigmoid(W_xi * X_t + W_hi * H_{t-1} + W_ci o C_{t-1} + b_i)      (8)
    f_t = sigmoid(W_xf * X_t + W_hf * H_{t-1} + W_cf o C_{t-1} + b_f)      (9)
    C_t = f_t o C_{t-1} + i_t o tanh(W_xc * X_t + W_hc * H_{t-1} + b_c)    (10)
    o_t = sigmoid(W_xo * X_t + W_ho * H_{t-1} + W_co o C_t + b_o)          (11)
    H_t = o_t o tanh(C_t)                                                  (12)

The peephole weights ``W_c.`` are per channel (shape ``(C, 1, 1)``), so the cell stays fully
convolutional and runs at any resolution. With ``peepholes=False`` the cell has exactly the
parameters of Keras' ``ConvLSTM2D`` (biased input convolution, unbiased recurrent convolution),
which the authors used. Dropout (the paper: 0.4) acts on the input ``X_t`` in training.
"""

from __future__ import annotations

import torch
from torch import nn

__all__ = ["ConvLSTMCell", "LSTMState"]

LSTMState = tuple[torch.Tensor, torch.Tensor]


class ConvLSTMCell(nn.Module):
    """One ConvLSTM step; call it once per frame and pass the returned state to the next call.

    Args:
        in_channels: channels of ``X_t``.
        hidden_channels: channels of ``H_t`` and ``C_t`` (the paper: 512 units).
        kernel_size: odd kernel size of ``W_x.`` and ``W_h.`` (the paper: 3).
        dropout: probability of zeroing an input element in training.
        peepholes: include ``W_ci``, ``W_cf``, ``W_co``.
    """

    def __init__(
        self,
        in_channels: int,
        hidden_channels: int,
        kernel_size: int = 3,
        *,
        dropout: float = 0.4,
        peepholes: bool = True,
    ) -> None:
        super().__init__()
        if kernel_size % 2 != 1:
            raise ValueError(f"kernel_size must be odd, got {kernel_size}")
        self.hidden_channels = hidden_channels
        padding = kernel_size // 2
        # Gate order in the stacked convolutions: input, forget, cell, output.
        self.input_conv = nn.Conv2d(in_channels, 4 * hidden_channels, kernel_size, padding=padding)
        self.recurrent_conv = nn.Conv2d(
            hidden_channels, 4 * hidden_channels, kernel_size, padding=padding, bias=False
        )
        self.dropout = nn.Dropout(dropout)
        self.peepholes = peepholes
        if peepholes:
            self.peephole = nn.Parameter(torch.zeros(3, hidden_channels, 1, 1))
        else:
            self.register_parameter("peephole", None)
        with torch.no_grad():  # forget-gate bias 1, as Keras' unit_forget_bias
            self.input_conv.bias.zero_()
            self.input_conv.bias[hidden_channels : 2 * hidden_channels] = 1.0

    def initial_state(self, x: torch.Tensor) -> LSTMState:
        """Zero hidden and cell state matching the batch, size, dtype and device of ``x``."""
        batch, _, height, width = x.shape
        zeros = x.new_zeros(batch, self.hidden_channels, height, width)
        return zeros, zeros.clone()

    def forward(self, x: torch.Tensor, state: LSTMState | None = None) -> LSTMState:
        """Advance one frame: ``x`` is ``(B, C_in, H, W)``; returns the new ``(H_t, C_t)``."""
        gates = self.input_conv(self.dropout(x))
        if state is None:
            # Zero state (first frame, single images): every term with H_{t-1} or C_{t-1} in
            # Eq. 8-10 vanishes, so skip the recurrent convolution (half the cell's arithmetic).
            gate_i, _, gate_c, gate_o = gates.chunk(4, dim=1)
            cell = torch.sigmoid(gate_i) * torch.tanh(gate_c)
        else:
            hidden, cell = state
            gates = gates + self.recurrent_conv(hidden)
            gate_i, gate_f, gate_c, gate_o = gates.chunk(4, dim=1)
            if self.peepholes:
                gate_i = gate_i + self.peephole[0] * cell
                gate_f = gate_f + self.peephole[1] * cell
            cell = torch.sigmoid(gate_f) * cell + torch.sigmoid(gate_i) * torch.tanh(gate_c)
        if self.peepholes:
            gate_o = gate_o + self.peephole[2] * cell
        hidden = torch.sigmoid(gate_o) * torch.tanh(cell)
        return hidden, cell
