"""torch.hub entry points: every shipped model by its alias and tag, as a network in eval mode.

    model = torch.hub.load("path/to/dualpixel", "rdpd_light", source="local")
    model = torch.hub.load("path/to/dualpixel", "rdpd_light_v12", source="local",
                           device="cpu")

Names are the registry's aliases and tags with ``-`` and ``.`` as ``_``. The weights ship
inside the package: nothing is downloaded. Deblur with :func:`dualpixel.deblur` (``model=``
the network).
"""

import sys as _sys
from pathlib import Path as _Path  # only entry points are public callables here

dependencies = ["torch", "numpy", "scipy", "cv2", "safetensors", "skimage", "click", "yaml"]

try:
    import dualpixel  # noqa: F401  (installed)
except ImportError:  # a clone that is not installed: its source folder
    _sys.path.insert(0, str(_Path(__file__).resolve().parent / "src"))

from dualpixel.weights import ALIASES, WEIGHTS  # noqa: E402


def _entry_point(name: str):
    def load(device: str = "auto"):
        from dualpixel.api import load_model

        return load_model(name, device=device)

    load.__name__ = name.replace("-", "_").replace(".", "_")
    load.__doc__ = f"The shipped model {name!r} ({ALIASES.get(name, name)}), in eval mode."
    return load


for _name in [*ALIASES, *WEIGHTS]:
    _load = _entry_point(_name)
    globals()[_load.__name__] = _load
