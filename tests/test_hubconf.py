"""torch.hub loads the shipped models from a clone by alias, tag and preset (``hubconf.py``)."""

from pathlib import Path

import torch

from dualpixel.models import count_parameters
from dualpixel.weights import ALIASES, DEFAULT_CHECKPOINT, PRESETS, WEIGHTS

ROOT = Path(__file__).resolve().parents[1]


def test_every_alias_and_tag_is_an_entry_point():
    import importlib.util

    spec = importlib.util.spec_from_file_location("hubconf", ROOT / "hubconf.py")
    hubconf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hubconf)
    names = {n for n in dir(hubconf) if callable(getattr(hubconf, n)) and not n.startswith("_")}
    assert names == {n.replace("-", "_").replace(".", "_")
                     for n in [*ALIASES, *WEIGHTS, *PRESETS]}


def test_the_default_loads_through_torch_hub():
    entry = DEFAULT_CHECKPOINT.replace("-", "_")
    model = torch.hub.load(str(ROOT), entry, source="local", device="cpu")
    assert not model.training
    assert count_parameters(model) == WEIGHTS[ALIASES[DEFAULT_CHECKPOINT]].num_params


def test_a_preset_loads_through_torch_hub_with_its_settings():
    model = torch.hub.load(str(ROOT), "rdpd_light_video", source="local", device="cpu")
    assert model.output_settings["fuse_frames"] == PRESETS["rdpd-light-video"].output[
        "fuse_frames"]


def test_hubconf_imports_nothing_before_torch_checks_its_dependencies():
    """Issue #73: torch.hub imports hubconf.py, then checks ``dependencies``; a module-level
    import of the package (and so NumPy) gave a bare ``ModuleNotFoundError: numpy`` where
    torch.hub would have named the missing dependency. Module level holds the standard library
    only, and the entry points load the clone's package, not another installed one."""
    import ast

    tree = ast.parse((ROOT / "hubconf.py").read_text())
    top = set()
    for node in tree.body:  # module level only: the entry points import inside themselves
        if isinstance(node, ast.Import):
            top |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            top.add(str(node.module).split(".")[0])
    assert top <= {"json", "sys", "pathlib"}, top
    import importlib.util

    spec = importlib.util.spec_from_file_location("hubconf_probe", ROOT / "hubconf.py")
    hubconf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hubconf)
    model = hubconf.rdpd_light(device="cpu")
    import dualpixel

    assert Path(dualpixel.__file__).is_relative_to(ROOT / "src")
    assert model.output_settings == {"brightness": "tied"}
