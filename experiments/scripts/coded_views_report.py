"""The table of what coded_views.sh measured (issue #54): per set, each model's gain over the
input on the clean and the coded copy, and v15 - v12 on both.

    python experiments/scripts/coded_views_report.py runs/coded-views
"""

from __future__ import annotations

import sys
from pathlib import Path

from decide_seventh import gain

SETS = ["canon-840-gif", "canon-hd-jpeg80", "dslr-jpeg80", "phone-jpeg80"]
MODELS = ["rdpd-light.v15", "rdpd-light.v12", "rdpd-wide.v2"]


def main(out: Path) -> None:
    print("| set | " + " | ".join(f"{m}: clean / coded" for m in MODELS)
          + " | v15 - v12: clean / coded |")
    print("|---|" + "---|" * (len(MODELS) + 1))
    for name in SETS:
        clean = name.rsplit("-", 1)[0] + "-clean"
        g = {(m, kind): gain(out / "eval" / (clean if kind == "clean" else name) / m)
             for m in MODELS for kind in ("clean", "coded")}
        cells = [f"{g[m, 'clean']:+.2f} / {g[m, 'coded']:+.2f}" for m in MODELS]
        diff = [g["rdpd-light.v15", k] - g["rdpd-light.v12", k] for k in ("clean", "coded")]
        print(f"| {name} | " + " | ".join(cells) + f" | {diff[0]:+.2f} / {diff[1]:+.2f} |")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "runs/coded-views"))
