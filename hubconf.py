"""torch.hub entry points: every shipped model by its alias, tag and preset, as a network in
eval mode.

    model = torch.hub.load("path/to/dualpixel", "rdpd_light", source="local")
    model = torch.hub.load("path/to/dualpixel", "rdpd_light_v18", source="local",
                           device="cpu")

Names are the registry's aliases, tags and presets with ``-`` and ``.`` as ``_``. The weights ship
inside the package: nothing is downloaded. Deblur with :func:`dualpixel.deblur` (``model=``
the network): it runs as the shipped model runs (its output settings travel with it).

The entry points are read from the registry file alone, so torch.hub can check
``dependencies`` before anything of the package (and NumPy) is imported; the package then
comes from this clone's ``src/``, whichever dualpixel is installed besides.
"""

import json as _json
import sys as _sys
from pathlib import Path as _Path  # only entry points are public callables here

dependencies = ["torch", "numpy", "scipy", "cv2", "safetensors", "skimage", "click", "yaml"]

_SOURCE = _Path(__file__).resolve().parent / "src"
_REGISTRY = _json.loads((_SOURCE / "dualpixel" / "weights" / "registry.json").read_text("utf-8"))


def _entry_point(name: str):
    def load(device: str = "auto"):
        loaded = _sys.modules.get("dualpixel")
        if loaded is None and str(_SOURCE) not in _sys.path:
            _sys.path.insert(0, str(_SOURCE))  # this clone's package, not another installed one
        elif loaded is not None and not str(loaded.__file__).startswith(str(_SOURCE)):
            import warnings

            warnings.warn(f"dualpixel was imported from {_Path(loaded.__file__).parent} before "
                          f"torch.hub; its weights are used, not those of {_SOURCE}",
                          stacklevel=2)
        from dualpixel.api import load_model

        return load_model(name, device=device)

    load.__name__ = name.replace("-", "_").replace(".", "_")
    preset = _REGISTRY.get("presets", {}).get(name)
    tag = preset["weights"] if preset else _REGISTRY["aliases"].get(name, name)
    load.__doc__ = f"The shipped model {name!r} ({tag}), in eval mode."
    if preset:
        load.__doc__ += f" A preset: its weights run with {preset['output']}."
    return load


for _name in [*_REGISTRY["aliases"], *_REGISTRY["weights"], *_REGISTRY.get("presets", {})]:
    _load = _entry_point(_name)
    globals()[_load.__name__] = _load
