"""Every config the project ships loads: no stale or misspelled keys, valid values."""

from pathlib import Path

import pytest

from dualpixel.training import load_config

CONFIGS = sorted((Path(__file__).resolve().parents[2] / "configs").glob("*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_config_loads(path):
    config = load_config(path)
    assert config.synthetic_data or config.real_data


def test_there_are_configs():
    assert len(CONFIGS) >= 10
