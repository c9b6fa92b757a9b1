"""torch.hub loads the shipped models from a clone by alias and tag (``hubconf.py``)."""

from pathlib import Path

import torch

from dualpixel.models import count_parameters
from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, WEIGHTS

ROOT = Path(__file__).resolve().parents[1]


def test_every_alias_and_tag_is_an_entry_point():
    import importlib.util

    spec = importlib.util.spec_from_file_location("hubconf", ROOT / "hubconf.py")
    hubconf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hubconf)
    names = {n for n in dir(hubconf) if callable(getattr(hubconf, n)) and not n.startswith("_")}
    assert names == {n.replace("-", "_").replace(".", "_") for n in [*ALIASES, *WEIGHTS]}


def test_the_default_loads_through_torch_hub():
    entry = DEFAULT_CHECKPOINT.replace("-", "_")
    model = torch.hub.load(str(ROOT), entry, source="local", device="cpu")
    assert not model.training
    assert count_parameters(model) == WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].num_params
