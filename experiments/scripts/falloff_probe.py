"""Issue #77 item 3: can the default learn to read a disparity ratio that falls towards the
frame's sides?

Swapping the views' halves (``formation_radius_map.py --swap``) says that the real 1620-px dev
views' difference departs from ours at the sides by the measured falloff, which costs the default
about 1 dB on side tiles of our own views rendered with it (``--ratio-profile 1.234 0.544``).
Two arms from the default, alike but for the Canon cameras' ``disparity_falloff``
(``coded_training.py``'s measured values): ``control`` and ``falloff``, each ``--iterations`` of
the coded recipe's on-the-fly sources (:func:`in_focus_probe.make_arm`) on the scenes in
``DATA/data/scenes-train`` (e.g. 160 of the photographic recipe's, ``dualpixel scenes ...
--sequences 160 --seed 50000``), validated on ``DATA/data/val``. Then each arm's weights go to
``formation_radius_map.py`` (``--swap`` off) with and without the falloff in the re-render; read
the side tiles (|x| >= 0.6).

    python experiments/scripts/falloff_probe.py runs/falloff --data runs/falloff --iterations 600
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from coded_training import fall_off_towards_the_sides  # beside this script
from in_focus_probe import arm_arguments, make_arm

#: ``formation_radius_map.py`` on the 1620-px dev scenes, as the swap was measured.
RADIUS_MAP = ["experiments/scripts/formation_radius_map.py", "../shared/data/canon-dp-real-hd",
              "--camera", "canon-hd-linear", "--max-radius", "20", "--tile", "64", "--margin",
              "16", "--toned", "--registered", "--h264", "23"]
PROFILE = ("1.234", "0.544")  # the falloff measured on the dev views (docs/formation.md)


def main() -> None:
    args = arm_arguments(__doc__.splitlines()[0]).parse_args()
    val = [str(args.data / "data" / "val")]
    weights = {"control": make_arm("control", (0.0, 0.0), args.output, args.data,
                                   args.iterations, args.threads, val_data=val)}
    fall_off_towards_the_sides()  # from here on, every Canon camera falls off
    weights["falloff"] = make_arm("falloff", (0.0, 0.0), args.output, args.data,
                                  args.iterations, args.threads, val_data=val)
    for name, path in weights.items():
        for label, profile in (("flat", ()), ("falloff-views", ("--ratio-profile", *PROFILE))):
            log = args.output / f"map-{name}-{label}.log"
            if not log.is_file():
                with open(f"{log}.part", "w") as out:
                    subprocess.run([sys.executable, *RADIUS_MAP, "--model", str(path),
                                    "--threads", str(args.threads), *profile],
                                   check=True, stdout=out)
                Path(f"{log}.part").rename(log)
            print(f"{name}, {label}:\n" + log.read_text().split("\n\n")[-1], flush=True)


if __name__ == "__main__":
    main()
