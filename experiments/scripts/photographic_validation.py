"""The photographic held-out sets of recipes/rdpd-light-photographs.yaml (every camera of the
family on scenes made of the validation photographs), made once, and the shipped models scored
on them (issue #77, item 2: does this validation rank v15 > v12 > rdpd-wide.v2, as the real
photographs do?). Resumable: each step skips what it finished. About 25 minutes on 2 cores.

    python experiments/scripts/photographic_validation.py [OUT]   # default runs/photo-val
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from statistics import mean

from decide_seventh import gain

from dualpixel.training.recipe import load_recipe, run_data

ROOT = Path(__file__).resolve().parents[2]
RECIPE = ROOT / "recipes" / "rdpd-light-photographs.yaml"
MODELS = ["rdpd-light.v15", "rdpd-light.v12", "rdpd-wide.v2"]


def main(out: Path) -> None:
    recipe = load_recipe(RECIPE)
    held_out = dataclasses.replace(recipe, data=[s for s in recipe.data
                                                 if s.name.endswith("-test")])
    run_data(held_out, out, workers=2, progress=False)
    sets = [s.name for s in held_out.data if s.kind == "synth"]
    table = {}
    for name in sets:
        for model in MODELS:
            report = out / "eval" / name / model
            if not (report / "summary.json").is_file():
                subprocess.run([str(ROOT / ".venv/bin/dualpixel"), "-q", "eval", "--dataset",
                                str(out / "data" / name), "--split", "test", "--checkpoint",
                                model, "--no-niqe", "--figures", "0", "-o", str(report)],
                               check=True, stdout=subprocess.DEVNULL)
            table[name, model] = gain(report)
        print(name, " ".join(f"{m} {table[name, m]:+.3f}" for m in MODELS), flush=True)
    print("| held-out set | " + " | ".join(MODELS) + " | v15 > v12 > wide |")
    print("|---|" + "---|" * (len(MODELS) + 1))
    for name in sets:
        g = [table[name, m] for m in MODELS]
        print(f"| {name} | " + " | ".join(f"{x:+.2f}" for x in g)
              + f" | {'yes' if g[0] > g[1] > g[2] else 'no'} |")
    means = [mean(table[n, m] for n in sets) for m in MODELS]
    print("| mean | " + " | ".join(f"{x:+.2f}" for x in means) + " | |")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "runs" / "photo-val")
