"""The CUDA paths (issue #76): skipped without a GPU, run on the device machine whenever one is
lent (`python -m pytest tests/gpu`); each compares the GPU's result with the CPU's.

``DUALPIXEL_GPU_TESTS=cpu`` runs them on the CPU instead, to check the tests themselves on a
machine without a GPU (the comparisons then hold trivially or to float rounding)."""

from __future__ import annotations

import os

import pytest
import torch


@pytest.fixture(scope="session")
def gpu() -> torch.device:
    if torch.cuda.is_available():
        return torch.device("cuda")
    if os.environ.get("DUALPIXEL_GPU_TESTS") == "cpu":
        return torch.device("cpu")
    pytest.skip("no CUDA device: the GPU tests run where one is lent (tests/gpu/conftest.py)")
