"""Issue #77 item 3: does a base blur of the in-focus optics in the formation teach the
sharpening the real 1620-px views need (docs/formation.md, "In focus, the real views are
softer")?

Two arms from the default, alike but for the formation of their training views: ``control``
the coded recipe's on-the-fly sources as they are (its ten-draw camera mix, half the display
views H.264-coded), ``soft`` the same with both views of every draw blurred by a Gaussian of std
drawn per sequence from ``--base-blur`` px (``SynthConfig.base_blur``; targets unchanged). Each
``--iterations`` of 8 crops of 256 px, learning rate 5e-5 cosine, from ``rdpd-light.v18``.
Then, for the default and both arms (tied brightness): the dev Canon scenes per scene
(`dualpixel eval`), three clean photographic held-out sets, and for the arms `check-model` on
``../shared/data/dp-real-nogt``; its table goes to ``OUT/scores.json``. Resumable (finished
arms and scores are kept).

    python experiments/scripts/in_focus_probe.py runs/in-focus --data runs/rdpd-light-photographs
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

from decide_seventh import real_pair_failures, scene_gains  # beside this script

from dualpixel.synthesis.on_the_fly import write_on_the_fly
from dualpixel.training import train
from dualpixel.training.recipe import load_recipe, phase_config, synth_config
from dualpixel.weights import resolve_tag

RECIPE = Path("recipes/rdpd-light-coded.yaml")
START = "rdpd-light.v18"
DEV = ("canon-dp-real", "canon-dp-real-hd")
HELD_OUT = ("canon-840", "canon-hd", "phone")


def make_arm(name: str, base_blur: tuple[float, float], out: Path, data: Path, iterations: int,
             threads: int, **training: object) -> Path:
    """Fine-tune the default on the coded recipe's sources with ``base_blur`` (and any other
    ``training`` settings, ``val_data`` included); its weights."""
    recipe = load_recipe(RECIPE)
    index = next(i for i, phase in enumerate(recipe.phases) if phase.name == "coded")
    settings = phase_config(recipe, index, data, str(resolve_tag(START)))
    sources = {}
    for folder in settings.synthetic_data:
        step = next(s for s in recipe.data if s.name == Path(folder).name)
        if step.name not in sources:
            config, source, fmt = synth_config(recipe, step, data)
            config = dataclasses.replace(config, base_blur=base_blur)
            folder = out / name / "sources" / step.name
            write_on_the_fly(folder, source, fmt, config)
            sources[step.name] = str(folder)
    settings = dataclasses.replace(settings, **{
        "synthetic_data": [sources[Path(f).name] for f in settings.synthetic_data],
        "val_data": [str(data / "data" / "canon-hd-test")], "val_limit": 4, "epochs": 1,
        "iterations_per_epoch": iterations, "learning_rate": 5e-5, "threads": threads,
        "workers": 0, "cache": True, "tensorboard": False, "checkpoint_minutes": 10,
        **training})
    run = out / name / "run"
    if not (run / "last.safetensors").is_file():
        train(settings, run, resume=(run / "last_state.pt").is_file(), progress=False)
    return run / "last.safetensors"


def evaluate(model: str, dataset: str, out: Path, *extra: str) -> Path:
    """`dualpixel eval` of ``model`` on ``dataset`` with tied brightness, once; its folder."""
    if not (out / "per_image.csv").is_file():
        subprocess.run([sys.executable, "-m", "dualpixel", "-q", "eval", "--dataset", dataset,
                        "--checkpoint", model, "--brightness", "tied", "--precision", "fp32",
                        "--no-niqe", "--figures", "0", *extra, "-o", str(out)], check=True,
                       stdout=subprocess.DEVNULL)
    return out


def scores_of(label: str, model: str, out: Path, data: Path, real_pairs: bool) -> dict:
    """Dev gains per scene, held-out gains and (``real_pairs``) the target-free failures."""
    found: dict = {}
    for dataset in DEV:
        found[dataset] = scene_gains(evaluate(model, f"../shared/data/{dataset}",
                                              out / "eval" / dataset / label))
    for camera in HELD_OUT:
        folder = evaluate(model, str(data / "data" / f"{camera}-test"),
                          out / "eval" / f"photo-{camera}" / label, "--split", "test")
        gains = scene_gains(folder)
        found[f"photo-{camera}"] = sum(gains.values()) / len(gains)
    if real_pairs:
        checks = out / "checks" / label
        if not (checks / "target_free.csv").is_file():
            subprocess.run([sys.executable, "-m", "dualpixel", "-q", "check-model", "--input",
                            "../shared/data/dp-real-nogt", "--checkpoint", model,
                            "--brightness", "tied", "--overshoot", "model", "--flips", "off",
                            "-o", str(checks)], check=True, stdout=subprocess.DEVNULL)
        rows = [{**r, "pair": f"dp-real-nogt/{r['pair']}"}  # one input: names alone
                for r in csv.DictReader(open(checks / "target_free.csv"))
                if r["method"].endswith("+tied")]
        found["target-free failures"] = real_pair_failures(rows)
    return found


def arm_arguments(description: str) -> argparse.ArgumentParser:
    """The options of a probe whose arms :func:`make_arm` trains: its folder, the data folder
    of the photographic recipe, the iterations of each arm and the threads."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("output", type=Path)
    parser.add_argument("--data", type=Path, default=Path("runs/rdpd-light-photographs"))
    parser.add_argument("--iterations", type=int, default=600)
    parser.add_argument("--threads", type=int, default=2)
    return parser


def main() -> None:
    parser = arm_arguments(__doc__.splitlines()[0])
    parser.add_argument("--base-blur", type=float, nargs=2, default=(0.0, 0.7))
    args = parser.parse_args()
    arms = {"control": (0.0, 0.0), "soft": tuple(args.base_blur)}
    models = {"default": START}
    for name, base_blur in arms.items():
        models[name] = str(make_arm(name, base_blur, args.output, args.data, args.iterations,
                                    args.threads))
    print_table(score_all(models, args.output, args.data))


def score_all(models: dict[str, str], out: Path, data: Path) -> dict:
    """:func:`scores_of` for each model (``default``: no target-free checks), kept in
    ``OUT/scores.json`` as each finishes."""
    path = out / "scores.json"
    table = json.loads(path.read_text()) if path.is_file() else {}
    for label, model in models.items():
        if label not in table:
            table[label] = scores_of(label, model, out, data, label != "default")
            path.write_text(json.dumps(table, indent=1))
    return table


def print_table(table: dict) -> None:
    """The scores as a Markdown table, a row per model."""
    print("| model | dev 840 | dev 1620 | worst dev scene | " + " | ".join(
        f"photo-{c}" for c in HELD_OUT) + " | target-free failures |")
    print("|---|---|---|---|" + "---|" * len(HELD_OUT) + "---|")
    for label, found in table.items():
        means = [sum(found[d].values()) / len(found[d]) for d in DEV]
        worst = min(min(found[d].values()) for d in DEV)
        held = " | ".join(f"{found[f'photo-{c}']:+.2f}" for c in HELD_OUT)
        failures = found.get("target-free failures")
        print(f"| {label} | {means[0]:+.3f} | {means[1]:+.3f} | {worst:+.2f} | {held} | "
              f"{'-' if failures is None else len(failures)} |")


if __name__ == "__main__":
    main()
